from __future__ import annotations

import json
from pathlib import Path

from typer.testing import CliRunner

from murk.cli.main import app
from murk.io import read_jsonl

runner = CliRunner()


def test_demo_quick_runs_the_whole_pipeline(tmp_path: Path) -> None:
    out = tmp_path / "demo"
    r = runner.invoke(app, ["demo", "--quick", "--out", str(out), "-q"])
    assert r.exit_code == 0, r.output
    assert len(list((out / "scenes" / "rgb").iterdir())) == 6
    recs = read_jsonl(out / "synth" / "manifest.jsonl")
    assert len(recs) == 6 and all(
        "N_p" in x and x["stages"] == ["basic", "forward_scatter", "marine_snow"] for x in recs
    )
    assert (out / "train" / "best.pt").exists()
    doc = json.loads((out / "report" / "metrics.json").read_text())
    labels = ["raw", "post", "jointid", "jointid+post", "lite", "train-illustration"]
    assert [m["label"] for m in doc["methods"]] == labels
    assert doc["methods"][2]["checkpoint"] is None  # the shipped weights, named in "weights"
    assert doc["methods"][2]["weights"].endswith("jointid-small.pt") and doc["methods"][0]["weights"] is None
    assert doc["methods"][4]["weights"].endswith("lite.pt") and doc["methods"][4]["blended_weights"] is None
    assert doc["methods"][2]["blended_weights"].endswith("lite.pt")  # jointid blends the shipped lite in
    assert doc["methods"][5]["blended_weights"] is None  # the illustration run: the network as trained
    assert len(doc["rows"]) == 3 * 6 and not doc["errors"]
    assert "report.html" in r.output and "jointid+post" in r.output and "shipped" in r.output
    # rerunning resumes: nothing is trained again
    mtime = (out / "train" / "best.pt").stat().st_mtime
    r = runner.invoke(app, ["demo", "--quick", "--out", str(out), "-q"])
    assert r.exit_code == 0 and (out / "train" / "best.pt").stat().st_mtime == mtime
