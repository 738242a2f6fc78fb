"""The restoration interface and the registry of methods by name.

A :class:`Restorer` takes a batch of float32 RGB images in [0, 1] and returns the enhanced batch, plus metric
depth when the method estimates it (Joint-ID does). Methods are registered by name (``post``, ``jointid``,
...); a spec ``"a+b"`` chains them left to right (``jointid+post`` = Joint-ID, then Eq. (9) on its output; the
depth of the chain is the last depth any stage produced), and ``"a|b@w"`` blends them: ``(1 - w) * a + w * b`` of
two restorations of the same input (:class:`Blend`; the depth of ``a``, else of ``b``); ``|`` binds tighter than
``+`` (the grammar: :mod:`murk.enhance.spec`). A spec may carry options after ``?`` (``post?lam=0.9``). A preset
(:class:`murk.enhance.declare.Preset`) is a method declared as such a spec: ``jointid`` is
``jointid_net|lite@lite_blend``. Each method is declared once (:class:`murk.enhance.declare.Method`: its
options, what it needs, the import path of its implementation); an option no method of the spec declares, or a
value outside its declared type or range, is an error (:mod:`murk.enhance.options`). This is murk's one registry of
methods (networks are built by their methods' implementations). Importing it imports neither torch nor OpenCV: the
built-in declarations (:data:`murk.enhance.methods.BUILTIN`) name their implementations by import path, imported
when a method is built, so names and options are checked before any network is loaded.

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

from murk._checks import check_range
from murk._suggest import did_you_mean
from murk.enhance.declare import Method, Option, Preset
from murk.enhance.options import check_given, declared_options, parse_spec, route_options
from murk.enhance.spec import ChainSpec, Node, Term, names, parse_method
from murk.enhance.temporal import FrameEMA

if TYPE_CHECKING:
    import torch


@dataclass(frozen=True)
class Restored:
    """A restored numpy batch: ``images`` (B, H, W, 3) float32 in [0, 1]; ``depth_m`` (B, H, W) or None;
    ``facts``: one dict per image of what the method estimated on the way (the ``water`` method: the water), which
    ``murk enhance`` records in ``estimates.jsonl``; None for methods that report nothing."""

    images: np.ndarray
    depth_m: np.ndarray | None = None
    facts: tuple[dict[str, Any], ...] | None = None


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
    frames) of floats in [0, 1]; a :class:`murk.errors.ShapeError` for another shape and a TypeError for integer
    values (8- or 16-bit frames: :func:`murk.io.to_float` converts them), each saying what it got."""
    from murk.errors import ShapeError

    try:
        batch = np.ascontiguousarray(images)
    except (TypeError, ValueError) as exc:  # ragged lists, objects numpy cannot hold
        raise ShapeError(f"images: expected a numpy batch (B, H, W, 3), got {type(images).__name__} ({exc})") from None
    if batch.ndim != 4 or batch.shape[3] != 3 or min(batch.shape[:3]) < 1:
        hint = " (one image (H, W, 3): pass images[None])" if batch.ndim == 3 and batch.shape[2] == 3 else ""
        raise ShapeError(f"images: expected shape (B, H, W, 3), got {batch.shape}{hint}")
    if not np.issubdtype(batch.dtype, np.floating):
        hint = " (murk.io.to_float converts 8- and 16-bit frames)" if np.issubdtype(batch.dtype, np.integer) else ""
        raise TypeError(f"images: expected a float array in [0, 1], got dtype {batch.dtype}{hint}")
    return batch


def check_tensor_batch(images: object) -> None:
    """Raise TypeError unless ``images`` is a floating-point torch tensor, :class:`murk.errors.ShapeError` unless it
    is a batch (B, 3, H, W) with B >= 1: the check of every network restorer's ``restore_tensor``."""
    import torch

    from murk.errors import ShapeError

    if not isinstance(images, torch.Tensor) or not images.is_floating_point():
        raise TypeError(f"images: expected a float tensor (B, 3, H, W) in [0, 1], got {type(images).__name__}")
    if images.ndim != 4 or images.shape[1] != 3 or images.shape[0] < 1:
        raise ShapeError(f"images: expected shape (B, 3, H, W), got {tuple(images.shape)}")


def torch_device(device: str | torch.device) -> torch.device:
    """``device`` as a torch device a network can run on here: ``cpu``, or ``cuda``/``cuda:N`` when CUDA is there.

    Raises:
        ValueError: CUDA is not available, or another kind of device.
    """
    import torch

    dev = torch.device(device)
    if dev.type == "cuda" and not torch.cuda.is_available():
        raise ValueError(
            f"device: CUDA is not available on this machine (torch {torch.__version__}), got {device!r}; use "
            "device cpu, or install a CUDA build of torch"
        )
    if dev.type not in ("cpu", "cuda"):
        raise ValueError(f"device: expected cpu, cuda or cuda:N, got {device!r}")
    return dev


class Restorer:
    """Base class of restoration methods. Subclasses set ``name`` and override ``restore`` and/or
    ``restore_tensor``; ``device`` is where the tensor path runs."""

    name: str = "restorer"
    device: torch.device = _CPUDevice()  # type: ignore[assignment]
    weights: str | None = None
    """The weights file the method loaded (set by the implementations of network methods); None without one."""
    base_weights: str | None = None
    """The weights of a network the method runs inside itself and builds on (``water``'s Joint-ID, which gives it
    distance and colour); None without one."""

    def restore(self, images: np.ndarray) -> Restored:
        """Restore a numpy batch (B, H, W, 3) float32 in [0, 1].

        Raises:
            ShapeError: not a batch (B, H, W, 3) (one image (H, W, 3) is ``images[None]``).
            TypeError: integer values (8- or 16-bit frames: :func:`murk.io.to_float` converts them).
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


class NetworkRestorer(Restorer):
    """A restorer around a torch network: :meth:`restore_tensor` checks the batch and hands it, as float32 on
    ``device``, to :meth:`_restore_network` under ``torch.inference_mode()``."""

    def restore_tensor(self, images: torch.Tensor) -> RestoredTensor:
        """Enhance a batch (B, 3, H, W) in [0, 1] of any H, W >= 1 (with its depth in metres when the network
        estimates it).

        Raises:
            TypeError: not a floating-point tensor.
            ShapeError: not (B, 3, H, W).
        """
        import torch

        check_tensor_batch(images)
        with torch.inference_mode():
            return self._restore_network(images, images.to(self.device, torch.float32))

    def _restore_network(self, images: torch.Tensor, x: torch.Tensor) -> RestoredTensor:
        """The restoration of ``images``; ``x`` is ``images`` as float32 on the device."""
        raise NotImplementedError


class _Composite(Restorer):
    """A restorer made of others (a chain's stages, a blend's members): their state over time is its own."""

    @property
    def parts(self) -> tuple[Restorer, ...]:
        raise NotImplementedError

    @property
    def carries_state(self) -> bool:
        return any(part.carries_state for part in self.parts)

    @contextlib.contextmanager
    def sequence(self) -> Iterator[None]:
        with contextlib.ExitStack() as stack:
            for part in self.parts:
                stack.enter_context(part.sequence())
            yield


class Chain(_Composite):
    """Stages applied left to right; keeps the last depth any stage produced."""

    def __init__(self, stages: list[Restorer]) -> None:
        if not stages:
            raise ValueError("stages: expected at least one restorer")
        self.stages = stages
        self.name = "+".join(s.name for s in stages)
        device = _set_device(stages[0])  # a chain of methods that set no device keeps the lazy CPU default
        if device is not None:
            self.device = device

    @property
    def parts(self) -> tuple[Restorer, ...]:
        return tuple(self.stages)

    def restore(self, images: np.ndarray) -> Restored:
        depth, facts = None, None
        for stage in self.stages:
            out = stage.restore(images)
            images, depth = out.images, out.depth_m if out.depth_m is not None else depth
            facts = out.facts if out.facts is not None else facts
        return Restored(images, depth, facts)

    def restore_tensor(self, images: torch.Tensor) -> RestoredTensor:
        depth = None
        for stage in self.stages:
            out = stage.restore_tensor(images.to(stage.device))
            images, depth = out.images, out.depth_m if out.depth_m is not None else depth
        return RestoredTensor(images, depth)


class Blend(_Composite):
    """``(1 - weight) * left + weight * right`` of two restorations of the same input (the spec ``left|right@w``);
    the depth of ``left``, else of ``right``.

    Members that run on torch (they set a device: the networks) are blended on the device, with ``torch.lerp``,
    also for numpy batches; members that do not (the classical methods, ``post`` on the CPU) are blended in numpy,
    without importing torch.

    Args:
        left, right: the two restorers.
        weight: ``right``'s share, in [0, 1].
        weight_label: what the weight is called where it was set (a preset's option, ``lite_blend``); None for a
            number in the spec. Shown in the weights line of ``murk enhance``.

    Raises:
        ValueError: a weight outside [0, 1].
    """

    def __init__(self, left: Restorer, right: Restorer, weight: float, weight_label: str | None = None) -> None:
        self.left, self.right = left, right
        self.weight = check_range("weight", weight, 0.0, 1.0)
        self.weight_label = weight_label
        self.name = f"{_grouped(left)}|{_grouped(right)}@{self.weight:g}"
        device = _set_device(left)
        device = _set_device(right) if device is None else device
        if device is not None:
            self.device = device

    @property
    def parts(self) -> tuple[Restorer, ...]:
        return self.left, self.right

    def restore(self, images: np.ndarray) -> Restored:
        if _set_device(self.left) is not None or _set_device(self.right) is not None:
            return super().restore(images)  # through restore_tensor: one lerp on the device
        a, b = self.left.restore(images), self.right.restore(images)
        return Restored(_lerp(a.images, b.images, self.weight), a.depth_m if a.depth_m is not None else b.depth_m)

    def restore_tensor(self, images: torch.Tensor) -> RestoredTensor:
        import torch

        a = self.left.restore_tensor(images.to(self.left.device))
        b = self.right.restore_tensor(images.to(self.right.device))
        with torch.inference_mode():
            blended = torch.lerp(a.images, b.images.to(a.images.device), self.weight)
        depth = a.depth_m if a.depth_m is not None else b.depth_m
        return RestoredTensor(blended, None if depth is None else depth.to(blended.device))

    def __repr__(self) -> str:
        return f"Blend({self.left!r}, {self.right!r}, weight={self.weight:g})"


def _grouped(restorer: Restorer) -> str:
    """A member's name in a blend's name: a chain in parentheses, as the spec writes it."""
    return f"({restorer.name})" if isinstance(restorer, Chain) else restorer.name


def _lerp(a: np.ndarray, b: np.ndarray, weight: float) -> np.ndarray:
    """``(1 - weight) * a + weight * b`` in float32, in torch.lerp's two forms (exact at both ends)."""
    diff = b - a
    if weight < 0.5:
        return a + np.float32(weight) * diff
    return b - diff * np.float32(1.0 - weight)


Factory = Callable[..., Restorer]
Preflight = Callable[..., None]
Declaration = Method | Preset
_REGISTRY: dict[str, Declaration | Factory] = {}


def register(method: Declaration | str, *, preflight: Preflight | None = None) -> Any:
    """Register a method: its :class:`~murk.enhance.declare.Method` declaration (``register(Method(...))``, the
    form of every built-in method, :mod:`murk.enhance.methods`) or :class:`~murk.enhance.declare.Preset`, or, as a
    decorator, a factory
    ``f(*, option=default, ...) -> Restorer`` whose signature declares the options (``@register("mine")``; a quick
    form for tests and scripts: no help or ranges). A name registered again is replaced.

    ``preflight`` (decorator form; a declaration carries its own), called by :func:`check` with ``files=True`` with
    the options the factory would get, raises what the factory would raise about the files they name (a weights
    file that is not there) without reading them or importing torch.

    Raises:
        ValueError: an empty name, or one with white space, ``+``, ``|``, ``@``, parentheses, ``?``, ``,`` or ``=``.
        TypeError: the factory does not declare its options as keyword-only parameters with defaults (e.g. it
            takes ``**kwargs``).
    """
    if isinstance(method, (Method, Preset)):
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


def _declared(name: str) -> Declaration:
    """The registered declaration of ``name``; a bare factory put into the registry (a test's monkeypatch) is read
    through its signature.

    Raises:
        ValueError: ``name`` is not registered (a preset that names a method nobody registered).
    """
    try:
        method = _REGISTRY[name]
    except KeyError:
        raise ValueError(f"method: unknown {name!r}; available: {', '.join(sorted(_REGISTRY))}") from None
    return method if isinstance(method, (Method, Preset)) else _from_factory(name, method)


def _option_map(name: str) -> dict[str, Option]:
    """The options of the method ``name``: its declaration's, or a preset's own and its first method's."""
    method = _declared(name)
    if isinstance(method, Preset):
        return {**_option_map(method.first), **{o.name: o for o in method.options}}
    return method.option_map


def unregister(name: str) -> None:
    """Remove the method ``name`` (a test's toy method); nothing when it is not registered."""
    _REGISTRY.pop(name, None)


def _first_line(factory: Callable[..., Any]) -> str:
    return (factory.__doc__ or "").strip().partition("\n")[0]


def available() -> list[str]:
    """Names of the registered methods."""
    _load_builtin()
    return sorted(_REGISTRY)


def declaration(name: str) -> Declaration:
    """The declaration of the method ``name`` (a :class:`~murk.enhance.declare.Method` or a
    :class:`~murk.enhance.declare.Preset`).

    Raises:
        ValueError: an unknown method name.
    """
    _load_builtin()
    if name not in _REGISTRY:
        raise ValueError(f"method: unknown {name!r}; available: {', '.join(sorted(_REGISTRY))}")
    return _declared(name)


@dataclass(frozen=True)
class WeightsUsed:
    """The weights files a restorer's output came from, found by walking the restorer a spec built (a chain's
    stages, a blend's members) down to the methods that loaded weights.

    Attributes:
        first: the first of them (left to right), e.g. Joint-ID's in ``jointid+post``; None without any.
        blended: the others that a blend averages into the output, each with its :class:`Blend` (the shipped
            ``lite`` of ``jointid``, whose blend's weight is ``lite_blend``).
        later: the others that a chain runs after the first, outside any blend (``detail`` in ``lite+detail``).
    """

    first: Restorer | None = None
    blended: tuple[tuple[Restorer, Blend], ...] = ()
    later: tuple[Restorer, ...] = ()

    @property
    def weights(self) -> str | None:
        """The file of :attr:`first` (None without one): ``weights`` in ``murk compare``'s metrics.json."""
        return None if self.first is None else str(self.first.weights)

    @property
    def blended_weights(self) -> str | None:
        """The files of :attr:`blended`, joined with ``"; "`` (None without any): ``blended_weights`` in
        ``murk compare``'s metrics.json."""
        return "; ".join(str(stage.weights) for stage, _ in self.blended) or None

    @property
    def base_weights(self) -> str | None:
        """The weights of the network :attr:`first` builds on (None without one): ``base_weights`` in ``murk
        compare``'s metrics.json (``water``'s Joint-ID)."""
        return None if self.first is None else self.first.base_weights

    @property
    def later_weights(self) -> str | None:
        """The files of :attr:`later`, joined with ``"; "`` (None without any): ``later_weights`` in ``murk
        compare``'s metrics.json."""
        return "; ".join(str(stage.weights) for stage in self.later) or None


def weights_used(restorer: Restorer | None) -> WeightsUsed:
    """Which weights files ``restorer``'s output came from (methods that loaded weights set ``weights``; None, the
    input itself: none)."""
    found: list[tuple[Restorer, Blend | None]] = []

    def walk(r: Restorer | None, blend: Blend | None) -> None:
        if isinstance(r, Chain):
            for stage in r.stages:
                walk(stage, blend)
        elif isinstance(r, Blend):
            walk(r.left, blend)
            walk(r.right, r)
        elif r is not None and r.weights:
            found.append((r, blend))

    walk(restorer, None)
    if not found:
        return WeightsUsed()
    return WeightsUsed(
        found[0][0],
        tuple((stage, blend) for stage, blend in found[1:] if blend is not None),
        tuple(stage for stage, blend in found[1:] if blend is None),
    )


def options_of(name: str) -> dict[str, Option]:
    """The options the method ``name`` declares (name, type, default, help, range), by name.

    Raises:
        ValueError: an unknown method name.
    """
    declaration(name)
    return _option_map(name)


def create(
    spec: str, *, shared: dict[str, Any] | None = None, given: Mapping[str, str] | None = None, **options: Any
) -> Restorer:
    """Build the restorer for ``spec`` (``"post"``, ``"jointid"``, ``"jointid+post"``, ``"post?lam=0.9"``,
    ``"jointid_net|lite@0.3"``, ...).

    Args:
        spec: method names chained with ``+`` and blended with ``|...@W`` (:mod:`murk.enhance.spec`), optionally
            followed by ``?KEY=VALUE,...`` options.
        shared: settings of the calling command (device, batch size, ...); each method takes the ones it
            declares. A name that no registered method declares is an error.
        given: names in ``shared`` that the user set explicitly, with how the user wrote them (``{"lam":
            "--lambda"}``): each must be declared by a method of ``spec`` (a flag the method ignores is an error).
        **options: method options (the spec's own win on a clash); each must be declared by at least one
            method of the spec, and goes to every method that declares it.

    Raises:
        ValueError: an unknown method name (the known ones are listed), a spec that does not parse (what was
            expected where), or an unknown or misspelt option (named, with the nearest valid name and the method's
            valid options).
    """
    tree, plan = _plan(spec, shared, given, options)
    restorer: Restorer = _make(tree, iter(plan), {}, build=True)
    return restorer


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
    tree, plan = _plan(spec, shared, given, options)
    if files:
        _make(tree, iter(plan), {}, build=False)


Plan = list[tuple[str, dict[str, Any]]]
"""Each method of a spec, left to right, with the options it takes."""


def _plan(
    spec: str, shared: dict[str, Any] | None, given: Mapping[str, str] | None, options: dict[str, Any]
) -> tuple[Node, Plan]:
    """The tree of ``spec`` and each of its methods with its options (validated)."""
    _load_builtin()
    spec, spec_options = parse_spec(spec)
    tree = parse_method(spec)
    used = names(tree)
    unknown = [n for n in dict.fromkeys(used) if n not in _REGISTRY]
    if unknown:
        hint = did_you_mean(unknown[0], _REGISTRY) if len(unknown) == 1 else ""
        raise ValueError(
            f"method: unknown {', '.join(repr(n) for n in unknown)}{hint}; "
            f"available: {', '.join(sorted(_REGISTRY))} (chain them with '+', blend them with 'A|B@W')"
        )
    declared = [_option_map(n) for n in used]
    every = {n: _option_map(n) for n in _REGISTRY}
    known = {o for options in every.values() for o in options}
    check_given(spec, declared, given or {}, every)
    kwargs = route_options(spec, declared, {**options, **spec_options}, shared or {}, known)
    return tree, list(zip(used, kwargs, strict=True))


def _make(node: Node, plan: Iterator[tuple[str, dict[str, Any]]], weights: Mapping[str, float], *, build: bool) -> Any:
    """Build the restorer of ``node`` (``build``), or run the preflights of its methods (None), taking each method's
    options from ``plan`` in order. A blend's member of weight 0 is left out (neither built nor checked);
    ``weights`` are the values of the weights a preset names."""
    if isinstance(node, Term):
        name, options = next(plan)
        return _make_method(name, options, build=build)
    if isinstance(node, ChainSpec):
        stages = [_make(part, plan, weights, build=build) for part in node.parts]
        return Chain(stages) if build else None
    weight = weights[node.weight] if isinstance(node.weight, str) else node.weight
    left = _make(node.left, plan, weights, build=build)
    if weight == 0.0:
        for _ in names(node.right):
            next(plan)
        return left
    right = _make(node.right, plan, weights, build=build)
    label = node.weight if isinstance(node.weight, str) else None
    return Blend(left, right, weight, label) if build else None


def _make_method(name: str, options: dict[str, Any], *, build: bool) -> Any:
    """One method of a spec: its implementation (or preflight), or, for a preset, its spec's methods."""
    method = _declared(name)
    if isinstance(method, Method):
        if build:
            return method.build(options)
        method.check_files(options)
        return None
    tree = parse_method(method.spec, named_weights=True)
    own = {o.name: o for o in method.options}
    weights = {w: check_range(w, options.get(w, o.default), 0.0, 1.0) for w, o in own.items()}
    plan = []
    for i, member in enumerate(names(tree)):
        declared = _option_map(member)
        takes = [k for k in options if k in declared and k not in own and (i == 0 or k in method.passes)]
        plan.append((member, {k: options[k] for k in takes}))
    made = _make(tree, iter(plan), weights, build=build)
    if made is not None:
        made.name = method.name  # what a preset builds is named after it
    return made


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
