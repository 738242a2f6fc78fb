"""The metric table: one row per metric, read by ``murk eval``, ``murk compare``, ``murk study``, the HTML report,
the CSV/JSON writers and training's evaluation (names, order, labels, units, directions and what each needs are
written here and nowhere else). Importing it imports no metric, numpy or torch: a row names its function by
import path, loaded on first use.

A row's function is called by what the metric needs (:data:`Needs`):

- ``none`` (no-reference): ``f(image, data_range=..., **settings)``;
- ``reference`` (full-reference): ``f(output, reference, data_range=..., **settings)``;
- ``input`` (input-vs-output restoration measures): ``f(input, output)``;
- ``depth``: ``f(pred_m, ref_m)``;
- ``snow_pair``: computed by ``murk compare --snow-clean`` from a pair of the same scene without and with snow
  (:mod:`murk.metrics.snow_pairs`).

``data_range`` says what the function is given: ``native`` (the image as read, uint8/uint16 or float, with
``data_range`` its peak: 255, 65535 or 1.0), ``unit`` (float RGB in [0, 1]; ``data_range=1.0`` where the call
takes one) or ``metres`` (depth maps). Rows that share a function (UIQM and its three terms) are computed with one
call; ``field`` picks the row's value out of the result (an attribute or a key).

Adding a metric is one row here (or :func:`register` from outside) plus its function; ``murk eval`` and
``murk compare`` then score it (``default=True``: in their default set; else when picked with
``murk eval --metrics NAME``).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

Better = Literal["higher", "lower"]
Needs = Literal["none", "reference", "input", "depth", "snow_pair"]
DataRange = Literal["native", "unit", "metres"]
NEEDS: tuple[Needs, ...] = ("none", "reference", "input", "depth", "snow_pair")


@dataclass(frozen=True)
class Metric:
    """One row of the metric table.

    Attributes:
        name: the column key in every table, CSV and JSON file (``psnr``).
        function: ``"module:function"`` computing it (called as its ``needs`` says; see the module docstring).
        label: the heading in reports, plain text (``PSNR``).
        unit: ``dB``, ``m``, ``m/m``, ``×`` (a ratio output/input), or empty.
        better: ``higher`` or ``lower``; None where neither is (an input's value, a ratio whose ideal is 1).
        needs: what it is computed from besides the image (:data:`Needs`).
        data_range: what the function expects (:data:`DataRange`).
        field: the attribute or key of the function's result that is this metric (None: the result itself).
        torch_function: ``"module:function"`` of its torch twin (a (B, 3, H, W) batch on its device), or None.
        default: scored by ``murk eval`` and ``murk compare`` unless metrics are picked (``--metrics``).
        headline: one of the few numbers short summaries show (training's log, the study's tables).
        digits: decimals shown in reports' tables.
        help: one line on what it measures.
    """

    name: str
    function: str
    label: str
    unit: str = ""
    better: Better | None = None
    needs: Needs = "none"
    data_range: DataRange = "unit"
    field: str | None = None
    torch_function: str | None = None
    default: bool = True
    headline: bool = False
    digits: int = 3
    help: str = ""

    def __post_init__(self) -> None:
        if not self.name.isidentifier():
            raise ValueError(f"name: expected a lower-case identifier, got {self.name!r}")
        for what, path in (("function", self.function), ("torch_function", self.torch_function)):
            if path is not None and path.count(":") != 1:
                raise ValueError(f"{what}: expected 'module:function', got {path!r}")
        if self.better not in ("higher", "lower", None):
            raise ValueError(f"better: expected 'higher', 'lower' or None, got {self.better!r}")
        if self.needs not in NEEDS:
            raise ValueError(f"needs: expected one of {', '.join(NEEDS)}, got {self.needs!r}")
        if self.data_range not in ("native", "unit", "metres"):
            raise ValueError(f"data_range: expected 'native', 'unit' or 'metres', got {self.data_range!r}")

    @property
    def heading(self) -> str:
        """The label with its unit (``PSNR dB``)."""
        return f"{self.label} {self.unit}".rstrip()

    @property
    def sign(self) -> float:
        """-1.0 where lower is better, else 1.0: ``sign * (a - b) > 0`` means ``a`` is better."""
        return -1.0 if self.better == "lower" else 1.0

    def load(self, *, torch: bool = False) -> Callable[..., Any]:
        """The function (``torch``: the torch twin), imported now.

        Raises:
            ValueError: no torch twin.
        """
        path = self.torch_function if torch else self.function
        if path is None:
            raise ValueError(f"metric {self.name}: has no torch twin")
        module, _, attr = path.partition(":")
        fn: Callable[..., Any] = getattr(importlib.import_module(module), attr)
        return fn

    def value(self, result: Any) -> Any:
        """This metric's value out of its function's ``result`` (a float, or a tensor from the torch twin)."""
        if self.field is None:
            return result
        return result[self.field] if isinstance(result, Mapping) else getattr(result, self.field)


def _uiqm(name: str, label: str, **kw: Any) -> Metric:
    return Metric(name, "murk.metrics.uiqm:uiqm", label, better="higher", data_range="native", field=name,
                  torch_function="murk.metrics.uiqm:uiqm_torch", **kw)  # fmt: skip


def _uciqe(name: str, label: str, **kw: Any) -> Metric:
    return Metric(name, "murk.metrics.uciqe:uciqe", label, better="higher", data_range="native", field=name,
                  torch_function="murk.metrics.uciqe:uciqe_torch", **kw)  # fmt: skip


def _ref(name: str, function: str, label: str, unit: str, better: Better, twin: str | None, **kw: Any) -> Metric:
    twin = None if twin is None else f"murk.metrics.{twin}"
    return Metric(name, f"murk.metrics.{function}", label, unit, better, "reference", torch_function=twin, **kw)


def _measure(name: str, label: str, unit: str = "", better: Better | None = None, **kw: Any) -> Metric:
    return Metric(name, "murk.metrics.fidelity:restoration_measures", label, unit, better, "input", field=name, **kw)


def _depth(name: str, label: str, unit: str, better: Better, **kw: Any) -> Metric:
    return Metric(name, "murk.metrics.depth:depth_errors", label, unit, better, "depth", "metres", field=name,
                  torch_function="murk.metrics.depth:depth_errors_torch", **kw)  # fmt: skip


def _snow(name: str, label: str, better: Better, function: str, field: str, help: str) -> Metric:
    return Metric(name, function, label, "", better, "snow_pair", field=field, help=help)


RATIO = "×"
"""The unit of an output/input ratio (1 = unchanged)."""

BUILTIN: tuple[Metric, ...] = (
    # no-reference quality of the image alone (Eq. (10) of the paper and UCIQE)
    _uiqm("uiqm", "UIQM", headline=True, help="underwater image quality measure, Eq. (10)"),
    _uiqm("uicm", "UICM", help="UIQM's colourfulness term"),
    _uiqm("uism", "UISM", help="UIQM's sharpness term"),
    _uiqm("uiconm", "UIConM", help="UIQM's contrast term"),
    _uciqe("uciqe", "UCIQE", headline=True, help="underwater colour image quality evaluation"),
    _uciqe("sigma_c", "chroma std", help="UCIQE's chroma standard deviation term"),
    _uciqe("con_l", "luminance contrast", help="UCIQE's luminance contrast term"),
    _uciqe("mu_s", "mean saturation", help="UCIQE's saturation term"),
    # full-reference scores against a reference image
    _ref("psnr", "reference:psnr", "PSNR", "dB", "higher", "reference:psnr_torch", digits=2,
         help="peak signal-to-noise ratio"),
    _ref("ssim", "reference:ssim", "SSIM", "", "higher", "reference:ssim_torch",
         help="structural similarity (11x11 Gaussian window unless --ssim-window uniform)"),
    _ref("ciede2000", "reference:ciede2000", "CIEDE2000", "", "lower", None, digits=2,
         help="mean CIEDE2000 colour difference"),
    _ref("affine_psnr", "affine_psnr:affine_fit_psnr", "PSNR after affine fit", "dB", "higher",
         "affine_psnr:affine_fit_psnr_torch", default=False, digits=2,
         help="PSNR after the best per-channel gain and offset onto the reference (a global colour fit forgiven)"),
    # input-vs-output restoration measures (murk.metrics.fidelity)
    _measure("artefact_periodic_ratio", "periodic artefacts", RATIO, "lower", headline=True,
             help="checkerboard/tiling energy, output/input"),
    _measure("artefact_isolated_ratio", "isolated artefacts", RATIO, "lower", headline=True,
             help="isolated-pixel noise energy, output/input"),
    _measure("structure_gms", "structure GMS", "", "higher", headline=True,
             help="mean gradient-magnitude similarity to the input (do the edges follow it)"),
    _measure("structure_gmsd", "structure GMSD", "", "lower", help="gradient-magnitude similarity deviation"),
    _measure("particles_bright_in", "bright particles in", "per Mpx", help="bright particles of the input"),
    _measure("particles_bright_out", "bright particles out", "per Mpx", help="bright particles of the output"),
    _measure("particles_dark_in", "dark particles in", "per Mpx", help="dark particles of the input"),
    _measure("particles_dark_out", "dark particles out", "per Mpx", help="dark particles of the output"),
    _measure("particle_residue_ratio", "particles", RATIO, "lower", headline=True,
             help="particles left, output/input"),
    _measure("cast_in", "colour cast in", help="colour cast of the input"),
    _measure("cast_out", "colour cast", "", "lower", headline=True, help="colour cast of the output"),
    _measure("luminance_in", "luminance in", help="mean luminance of the input"),
    _measure("luminance_out", "luminance out", help="mean luminance of the output"),
    _measure("luminance_ratio", "luminance", RATIO, headline=True, help="mean luminance, output/input"),
    _measure("contrast_in", "contrast in", help="luminance contrast of the input"),
    _measure("contrast_out", "contrast out", help="luminance contrast of the output"),
    _measure("contrast_ratio", "contrast", RATIO, headline=True, help="luminance contrast, output/input"),
    # depth errors against a reference depth map (Joint-ID's evaluator conventions)
    _depth("silog", "SILog", "", "lower", headline=True, help="scale-invariant log error x 100"),
    _depth("abs_rel", "AbsRel", "m/m", "lower", headline=True, help="mean |gt - pred| / gt"),
    _depth("abs_rel_median", "AbsRel median-scaled", "m/m", "lower", headline=True,
           help="AbsRel after scaling the prediction by median(gt) / median(pred)"),
    _depth("sq_rel", "SqRel", "m", "lower", help="mean (gt - pred)^2 / gt"),
    _depth("rmse", "RMSE", "m", "lower", headline=True, help="root mean square error"),
    _depth("log_rmse", "log RMSE", "", "lower", help="RMSE of ln depth"),
    _depth("log10", "log10", "", "lower", help="mean |log10 gt - log10 pred|"),
    _depth("d1", "delta<1.25", "", "higher", headline=True, help="share of pixels with max(gt/pred, pred/gt) < 1.25"),
    _depth("d2", "delta<1.25^2", "", "higher", help="share of pixels within 1.25^2"),
    _depth("d3", "delta<1.25^3", "", "higher", help="share of pixels within 1.25^3"),
    # marine snow on a pair of the same scene without and with snow (murk compare --snow-clean)
    _snow("snow_residue", "snow residue (pairs)", "lower", "murk.metrics.snow_pairs:snow_residue", "residue",
          "the particles' contrast left on the known sites (1 = kept, 0 = removed)"),
    _snow("snow_sites_left", "snow sites left", "lower", "murk.metrics.snow_pairs:snow_residue", "sites_left",
          "share of particle sites still at half their contrast or more"),
    _snow("snow_free_gms", "structure away from snow (GMS)", "higher", "murk.metrics.fidelity:structure_fidelity",
          "gms_mean", "structure fidelity to the snowy input 3 px or more from every site"),
    _snow("snow_colour_residue", "snow colour residue", "lower", "murk.metrics.snow_pairs:snow_residue",
          "colour_residue", "the particles' RGB difference left (a recoloured particle counts as left)"),
)  # fmt: skip

_TABLE: dict[str, Metric] = {}


def register(metric: Metric) -> Metric:
    """Add a row to the table (after the rows of its kind, so that columns stay grouped by what they need).

    Raises:
        TypeError: not a :class:`Metric`.
        ValueError: the name is taken.
    """
    if not isinstance(metric, Metric):
        raise TypeError(f"metric: expected a Metric, got {type(metric).__name__}")
    if metric.name in _TABLE:
        raise ValueError(f"metric {metric.name!r}: already in the table")
    _TABLE[metric.name] = metric
    return metric


def unregister(name: str) -> None:
    """Remove a row added by :func:`register` (tests); a built-in row stays."""
    if any(m.name == name for m in BUILTIN):
        raise ValueError(f"metric {name!r}: a built-in row cannot be removed")
    _TABLE.pop(name, None)


for _m in BUILTIN:
    register(_m)


def metrics(needs: Needs | None = None, *, default: bool | None = None) -> list[Metric]:
    """The rows in table order (grouped by :data:`NEEDS`, then as registered); ``needs``/``default`` filter."""
    rows = [m for kind in NEEDS for m in _TABLE.values() if m.needs == kind]
    return [m for m in rows if (needs is None or m.needs == needs) and (default is None or m.default == default)]


def names(needs: Needs | None = None, *, default: bool | None = None) -> tuple[str, ...]:
    """The names of :func:`metrics`."""
    return tuple(m.name for m in metrics(needs, default=default))


def get(name: str) -> Metric:
    """The row called ``name``.

    Raises:
        ValueError: no such metric (the message names the nearest and lists them all).
    """
    if name not in _TABLE:
        from murk._suggest import did_you_mean

        raise ValueError(f"metric: unknown {name!r}{did_you_mean(name, list(_TABLE))}; known: {', '.join(_TABLE)}")
    return _TABLE[name]


def pick(text: str | Iterable[str] | None) -> list[Metric] | None:
    """The rows named by ``text`` (``"psnr,ciede2000"`` or a list of names), in table order; None for None.

    Raises:
        ValueError: an unknown name, or none given.
    """
    if text is None:
        return None
    parts = text.split(",") if isinstance(text, str) else list(text)
    wanted = {get(p.strip()).name for p in parts if p.strip()}
    if not wanted:
        raise ValueError("metrics: expected at least one metric name")
    return [m for m in metrics() if m.name in wanted]


def compute(
    rows: Sequence[Metric],
    *args: Any,
    data_range: float | None = None,
    settings: Mapping[str, Mapping[str, Any]] | None = None,
    results: dict[str, Any] | None = None,
) -> dict[str, float]:
    """The values of ``rows`` (all of one :data:`Needs` kind) on the same arguments, by name. Each function is
    called once, as its kind says (``args``: the image, or output and reference, or input and output, or
    predicted and reference depth), with ``data_range`` when given and the keywords ``settings`` holds under its
    name (``{"uiqm": {"preset": "funie"}, "ssim": {"window": "uniform"}}``). ``results``, when given, collects
    each function's whole result by its path (e.g. every restoration measure, for the flags).
    """
    results = {} if results is None else results
    out: dict[str, float] = {}
    for m in rows:
        if m.function not in results:
            kw = dict((settings or {}).get(m.function.partition(":")[2], {}))
            if data_range is not None:
                kw["data_range"] = data_range
            results[m.function] = m.load()(*args, **kw)
        out[m.name] = m.value(results[m.function])
    return out


def describe(rows: Sequence[Metric] | None = None) -> str:
    """A plain-text table of the rows (``murk eval --list-metrics``)."""
    rows = metrics() if rows is None else rows
    head = ("name", "label", "unit", "better", "needs", "data range", "default", "what it measures")
    cells = [
        (m.name, m.label, m.unit or "-", m.better or "-", m.needs, m.data_range, "yes" if m.default else "no", m.help)
        for m in rows
    ]
    widths = [max(len(str(r[i])) for r in [head, *cells]) for i in range(len(head) - 1)]
    lines = [
        "  ".join(str(c).ljust(w) for c, w in zip(r[:-1], widths, strict=True)) + "  " + r[-1] for r in [head, *cells]
    ]
    return "\n".join(line.rstrip() for line in lines)
