"""``murk train``'s summary line names the best checkpoint in words, not as a Python dict."""

from __future__ import annotations

from murk.cli.train import _best_text


def test_best_checkpoint_is_printed_as_metric_value_and_step() -> None:
    assert _best_text({"metric": "val_psnr", "value": 16.2751, "step": 20}) == "val_psnr 16.28 at step 20"
    assert _best_text({}) == _best_text(None) == "-"
