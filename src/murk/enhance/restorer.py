"""The restoration interface and the registry of methods by name.

A :class:`Restorer` takes a batch of float32 RGB images in [0, 1] and returns the enhanced batch, plus metric
depth when the method estimates it (Joint-ID does). Methods are registered by name (``post``, ``jointid``,
...); a spec ``"a+b"`` chains them left to right (``jointid+post`` = Joint-ID, then Eq. (9) on its output),
and the depth of the chain is the last depth any stage produced. A spec may carry options after ``?``
(``post?lam=0.9``). Each method is declared once (:class:`murk.enhance.declare.Method`: its options, what it
needs, the import path of its implementation); an option no stage declares, or a value outside its declared type
or range, is an error (:mod:`murk.enhance.options`). This is murk's one registry of methods (networks are built
by their methods' implementations). Importing it imports neither torch nor OpenCV: the built-in declarations
(:data:`murk.enhance.methods.BUILTIN`) name their implementations by import path, imported when a method is
built, so names and options are checked before any network is loaded.

Two entry points per restorer:

- :meth:`Restorer.restore` on numpy batches (B, H, W, 3), what file/video pipelines use;
- :meth:`Restorer.restore_tensor` on torch batches (B, 3, H, W) on the restorer's device, so that chains on a
  GPU never leave the device. The default implementation of each one goes through the other, so a subclass
  overrides at least one of them.
"""

from __future__ import annotations

import contextlib
import inspect
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from murk._suggest import did_you_mean
from murk.enhance.declare import Method, Option
from murk.enhance.options import check_given, declared_options, parse_spec, route_options
from murk.enhance.temporal import FrameEMA

if TYPE_CHECKING:
    import torch


@dataclass(frozen=True)
class Restored:
    """A restored numpy batch: ``images`` (B, H, W, 3) float32 in [0, 1]; ``depth_m`` (B, H, W) or None."""

    images: np.ndarray
    depth_m: np.ndarray | None = None


@dataclass(frozen=True)
class RestoredTensor:
    """A restored torch batch: ``images`` (B, 3, H, W) in [0, 1]; ``depth_m`` (B, 1, H, W) or None."""

    images: torch.Tensor
    depth_m: torch.Tensor | None = None


class _CPUDevice:
    """The default ``Restorer.device``, ``torch.device("cpu")``, made when first read (so that importing this
    module, and with it the registry's names and options, does not import torch). A subclass or an instance
    that sets ``device`` replaces it."""

    def __get__(self, obj: object, owner: type | None = None) -> torch.device:
        import torch

        return torch.device("cpu")


def _set_device(restorer: object) -> Any | None:
    """The device ``restorer`` set (an instance or class attribute, a property's value), or None when it keeps the
    default CPU device, which is then not built (reading ``restorer.device`` would import torch)."""
    device = inspect.getattr_static(restorer, "device", None)
    if device is None or isinstance(device, _CPUDevice):
        return None
    return restorer.device if hasattr(device, "__get__") else device  # type: ignore[attr-defined]


def device_type(restorer: object) -> str:
    """The type of the device ``restorer`` runs on (``"cpu"``, ``"cuda"``, ...), read without importing torch
    for a method that never set a device (the classical ones, chains of them): so a caller can pick the CUDA
    path of a batch without making a CPU method pay torch's start-up."""
    device = _set_device(restorer)
    if device is None:
        return "cpu"
    return str(getattr(device, "type", device)).partition(":")[0]


def as_batch(images: object) -> np.ndarray:
    """``images`` as a contiguous numpy batch (B, H, W, 3) with B, H, W >= 1 (an array or a list of equal-size
    frames), or a :class:`murk.errors.ShapeError` saying what it got."""
    from murk.errors import ShapeError

    try:
        batch = np.ascontiguousarray(images)
    except (TypeError, ValueError) as exc:  # ragged lists, objects numpy cannot hold
        raise ShapeError(f"images: expected a numpy batch (B, H, W, 3), got {type(images).__name__} ({exc})") from None
    if batch.ndim != 4 or batch.shape[3] != 3 or min(batch.shape[:3]) < 1:
        hint = " (one image (H, W, 3): pass images[None])" if batch.ndim == 3 and batch.shape[2] == 3 else ""
        raise ShapeError(f"images: expected shape (B, H, W, 3), got {batch.shape}{hint}")
    return batch


class Restorer:
    """Base class of restoration methods. Subclasses set ``name`` and override ``restore`` and/or
    ``restore_tensor``; ``device`` is where the tensor path runs."""

    name: str = "restorer"
    device: torch.device = _CPUDevice()  # type: ignore[assignment]

    def restore(self, images: np.ndarray) -> Restored:
        """Restore a numpy batch (B, H, W, 3) float32 in [0, 1].

        Raises:
            ShapeError: not a batch (B, H, W, 3) (one image (H, W, 3) is ``images[None]``).
        """
        import torch

        if type(self).restore_tensor is Restorer.restore_tensor:
            raise NotImplementedError(f"{type(self).__name__} implements neither restore nor restore_tensor")
        x = torch.from_numpy(as_batch(images)).permute(0, 3, 1, 2).to(self.device, torch.float32)
        out = self.restore_tensor(x)
        imgs = out.images.detach().float().permute(0, 2, 3, 1).cpu().numpy()
        depth = None if out.depth_m is None else out.depth_m.detach().float()[:, 0].cpu().numpy()
        return Restored(np.ascontiguousarray(imgs), depth)

    def restore_tensor(self, images: torch.Tensor) -> RestoredTensor:
        """Restore a torch batch (B, 3, H, W) in [0, 1] on ``self.device``."""
        import torch

        if type(self).restore is Restorer.restore:
            raise NotImplementedError(f"{type(self).__name__} implements neither restore nor restore_tensor")
        out = self.restore(images.detach().float().permute(0, 2, 3, 1).cpu().numpy())
        imgs = torch.from_numpy(out.images).permute(0, 3, 1, 2).to(images.device)
        depth = None if out.depth_m is None else torch.from_numpy(out.depth_m)[:, None].to(images.device)
        return RestoredTensor(imgs, depth)

    def __call__(self, images: np.ndarray) -> Restored:
        return self.restore(images)

    temporal_state: FrameEMA | None = None
    """Set by methods with a ``temporal`` option > 0: their per-frame estimate's average over time."""
    _in_sequence: bool = False

    @contextlib.contextmanager
    def sequence(self) -> Iterator[None]:
        """Frames restored inside this block are consecutive frames of one video, in order: a method with a
        ``temporal`` weight (``post``, ``lite``) averages its per-frame estimate over them
        (:mod:`murk.enhance.temporal`), starting afresh at entry. Outside, every image is restored on its own."""
        if self.temporal_state is not None:
            self.temporal_state.reset()
        self._in_sequence = True
        try:
            yield
        finally:
            self._in_sequence = False

    @property
    def carries_state(self) -> bool:
        """Whether a frame's output inside :meth:`sequence` depends on the frames before it (a ``temporal``
        weight): a resumed video job must then restore the frames it skips, so that the rest comes out the same."""
        return self.temporal_state is not None

    def temporal_hook(self) -> FrameEMA | None:
        """The temporal average to apply now: inside :meth:`sequence` with a ``temporal`` weight, else None."""
        return self.temporal_state if self._in_sequence else None


class Chain(Restorer):
    """Stages applied left to right; keeps the last depth any stage produced."""

    def __init__(self, stages: list[Restorer]) -> None:
        if not stages:
            raise ValueError("stages: expected at least one restorer")
        self.stages = stages
        self.name = "+".join(s.name for s in stages)
        device = _set_device(stages[0])  # a chain of methods that set no device keeps the lazy CPU default
        if device is not None:
            self.device = device

    def restore(self, images: np.ndarray) -> Restored:
        depth = None
        for stage in self.stages:
            out = stage.restore(images)
            images, depth = out.images, out.depth_m if out.depth_m is not None else depth
        return Restored(images, depth)

    def restore_tensor(self, images: torch.Tensor) -> RestoredTensor:
        depth = None
        for stage in self.stages:
            out = stage.restore_tensor(images.to(stage.device))
            images, depth = out.images, out.depth_m if out.depth_m is not None else depth
        return RestoredTensor(images, depth)

    @property
    def carries_state(self) -> bool:
        return any(stage.carries_state for stage in self.stages)

    @contextlib.contextmanager
    def sequence(self) -> Iterator[None]:
        with contextlib.ExitStack() as stack:
            for stage in self.stages:
                stack.enter_context(stage.sequence())
            yield


Factory = Callable[..., Restorer]
Preflight = Callable[..., None]
_REGISTRY: dict[str, Method | Factory] = {}


def register(method: Method | str, *, preflight: Preflight | None = None) -> Any:
    """Register a method: its :class:`~murk.enhance.declare.Method` declaration (``register(Method(...))``, the
    form of every built-in method, :mod:`murk.enhance.methods`), or, as a decorator, a factory
    ``f(*, option=default, ...) -> Restorer`` whose signature declares the options (``@register("mine")``; a quick
    form for tests and scripts: no help or ranges). A name registered again is replaced.

    ``preflight`` (decorator form; a declaration carries its own), called by :func:`check` with ``files=True`` with
    the options the factory would get, raises what the factory would raise about the files they name (a weights
    file that is not there) without reading them or importing torch.

    Raises:
        ValueError: an empty name, or one with ``+``, ``?``, ``|``, ``,``, ``=`` or parentheses.
        TypeError: the factory does not declare its options as keyword-only parameters with defaults (e.g. it
            takes ``**kwargs``).
    """
    if isinstance(method, Method):
        _REGISTRY[method.name] = method
        return method
    name = method
    Method(name, "m:f")  # the name's rules

    def deco(factory: Factory) -> Factory:
        _REGISTRY[name] = _from_factory(name, factory, preflight)  # the contract is checked when registered
        return factory

    return deco


def _from_factory(name: str, factory: Factory, preflight: Preflight | None = None) -> Method:
    """The declaration a factory's signature makes (its keyword-only options; no help or ranges)."""
    options = tuple(declared_options(factory).values())
    return Method(name, lambda o: factory(**o), options, help=_first_line(factory), preflight=preflight)


def _declared(name: str) -> Method:
    """The registered declaration of ``name``; a bare factory put into the registry (a test's monkeypatch) is read
    through its signature."""
    method = _REGISTRY[name]
    return method if isinstance(method, Method) else _from_factory(name, method)


def unregister(name: str) -> None:
    """Remove the method ``name`` (a test's toy method); nothing when it is not registered."""
    _REGISTRY.pop(name, None)


def _first_line(factory: Callable[..., Any]) -> str:
    return (factory.__doc__ or "").strip().partition("\n")[0]


def available() -> list[str]:
    """Names of the registered methods."""
    _load_builtin()
    return sorted(_REGISTRY)


def declaration(name: str) -> Method:
    """The declaration of the method ``name``.

    Raises:
        ValueError: an unknown method name.
    """
    _load_builtin()
    if name not in _REGISTRY:
        raise ValueError(f"method: unknown {name!r}; available: {', '.join(sorted(_REGISTRY))}")
    return _declared(name)


def weighted_stage(restorer: Any) -> Any | None:
    """The first stage of a restorer (itself, or a stage of a chain) that loaded weights; None without one."""
    return next((s for s in getattr(restorer, "stages", [restorer]) if getattr(s, "weights", None)), None)


def weights_of(restorer: Any) -> str | None:
    """The weights file a restorer (or the first stage of a chain that has one) loaded, e.g. the shipped Joint-ID
    when no checkpoint was given; None for methods without weights."""
    stage = weighted_stage(restorer)
    return None if stage is None else str(stage.weights)


def blended_weights_of(restorer: Any) -> str | None:
    """The weights file of the restorer blended into the output of the stage that :func:`weights_of` names (the
    shipped ``lite`` of ``jointid?lite_blend``); None when nothing is blended in."""
    blended = getattr(getattr(weighted_stage(restorer), "lite", None), "weights", None)
    return None if blended is None else str(blended)


def options_of(name: str) -> dict[str, Option]:
    """The options the method ``name`` declares (name, type, default, help, range), by name.

    Raises:
        ValueError: an unknown method name.
    """
    return declaration(name).option_map


def create(
    spec: str, *, shared: dict[str, Any] | None = None, given: Mapping[str, str] | None = None, **options: Any
) -> Restorer:
    """Build the restorer for ``spec`` (``"post"``, ``"jointid"``, ``"jointid+post"``, ``"post?lam=0.9"``, ...).

    Args:
        spec: method names chained with ``+``, optionally followed by ``?KEY=VALUE,...`` options.
        shared: settings of the calling command (device, batch size, ...); each stage takes the ones it
            declares. A name that no registered method declares is an error.
        given: names in ``shared`` that the user set explicitly, with how the user wrote them (``{"lam":
            "--lambda"}``): each must be declared by a stage of ``spec`` (a flag the method ignores is an error).
        **options: method options (the spec's own win on a clash); each must be declared by at least one
            stage, and goes to every stage that declares it.

    Raises:
        ValueError: an unknown method name (the known ones are listed), or an unknown or misspelt option (named,
            with the nearest valid name and the method's valid options).
    """
    names, kwargs = _plan(spec, shared, given, options)
    stages = [_declared(n).build(kw) for n, kw in zip(names, kwargs, strict=True)]
    return stages[0] if len(stages) == 1 else Chain(stages)


def check(
    spec: str,
    *,
    shared: dict[str, Any] | None = None,
    given: Mapping[str, str] | None = None,
    files: bool = False,
    **options: Any,
) -> None:
    """Raise what :func:`create` would raise for these arguments about the method names and options, without
    building anything (no weights are read, torch is not imported): a command checks its ``--method`` at once.
    With ``files``, also what it would raise about the files the options name (a weights file that is not there;
    each method's ``preflight``, see :func:`register`): ``murk live`` says so before it opens its source.

    Raises:
        ValueError: as :func:`create`. InputFileError: with ``files``, a given weights file that is not there.
    """
    names, kwargs = _plan(spec, shared, given, options)
    if files:
        for name, kw in zip(names, kwargs, strict=True):
            _declared(name).check_files(kw)


def _plan(
    spec: str, shared: dict[str, Any] | None, given: Mapping[str, str] | None, options: dict[str, Any]
) -> tuple[list[str], list[dict[str, Any]]]:
    """The method names of ``spec`` and the keyword arguments of each stage's factory (validated)."""
    _load_builtin()
    spec, spec_options = parse_spec(spec)
    names = [n.strip() for n in spec.split("+")]
    unknown = [n for n in names if n not in _REGISTRY]
    if unknown or not all(names):
        hint = did_you_mean(unknown[0], _REGISTRY) if len(unknown) == 1 else ""
        raise ValueError(
            f"method: unknown {', '.join(repr(n) for n in unknown) or repr(spec)}{hint}; "
            f"available: {', '.join(sorted(_REGISTRY))} (chain them with '+')"
        )
    declared = [_declared(n).option_map for n in names]
    every = {n: _declared(n).option_map for n in _REGISTRY}
    known = {o for options in every.values() for o in options}
    check_given(spec, declared, given or {}, every)
    kwargs = route_options(spec, declared, {**options, **spec_options}, shared or {}, known)
    return names, kwargs


def _load_builtin() -> None:
    """Register the built-in methods (:data:`murk.enhance.methods.BUILTIN`, declarations that import neither torch
    nor OpenCV) once, so that names and options are known without loading any implementation."""
    global _LOADED
    if not _LOADED:
        from murk.enhance.methods import BUILTIN

        for method in BUILTIN:
            _REGISTRY.setdefault(method.name, method)
        _LOADED = True


_LOADED = False
