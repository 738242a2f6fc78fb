"""``murk water estimate`` as a library call: the water of each image (veil colour, attenuation per channel,
visibility in metres), estimated from the image and Joint-ID's distance map (:mod:`murk.models.water`).

An image that cannot be read is one error record (the :mod:`murk.io.jobs` schema); the others are estimated.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from murk.io.jobs import ErrorRecord
from murk.models.water import WaterInView


@dataclass(frozen=True)
class WaterOfImage:
    """One image's estimate: ``view`` (:class:`murk.models.water.WaterInView`: the water, its distances and whether
    the visibility is ``measurable``)."""

    path: Path
    view: WaterInView

    def as_dict(self) -> dict[str, object]:
        return {"image": str(self.path), **self.view.as_dict()}


def estimate_water(
    paths: Sequence[Path],
    *,
    depth_method: str = "jointid_net",
    estimator: Path | None = None,
    on_image: Callable[[WaterOfImage | ErrorRecord], None] | None = None,
    json_out: Path | None = None,
) -> list[WaterOfImage | ErrorRecord]:
    """Estimate the water of every image of ``paths`` (files, or folders of images), in order; with ``json_out``,
    write the estimates there too (JSON lines, one per image estimated, atomically).

    Raises:
        InputFileError: the estimator file cannot be read.
        ValueError: ``depth_method`` gives no distance map; ``json_out`` is an image it reads (named, or in a
            folder given), checked before any work (:func:`murk.io.paths.check_output_file`).
        OSError: ``json_out``'s folder cannot be made (before any work) or the file cannot be written.
    """
    import json

    from murk.enhance.restorer import create
    from murk.io.atomic import make_output_folder, write_text_atomic
    from murk.io.images import IMAGE_SUFFIXES, list_images, read_rgb
    from murk.io.paths import check_output_file
    from murk.models.water import load_water_estimator

    if json_out is not None:
        check_output_file(json_out, paths, option="--json", suffixes=IMAGE_SUFFIXES)
        make_output_folder(json_out.parent)  # a missing folder is made now, not after the work

    model = load_water_estimator(estimator)
    depth_net = create(depth_method)
    files: list[Path] = []
    results: list[WaterOfImage | ErrorRecord] = []
    for p in paths:
        if p.is_dir():
            found = list_images(p, recursive=True)
            files.extend(found)
            if not found:
                results.append(ErrorRecord(str(p), "list", f"{p}: folder holds no images"))
        else:
            files.append(p)
    for path in files:
        result: WaterOfImage | ErrorRecord
        try:
            image = read_rgb(path)
        except (OSError, ValueError) as exc:
            result = ErrorRecord(str(path), "read", str(exc))
        else:
            dist = depth_net.restore(image[None]).depth_m
            if dist is None:
                raise ValueError(f"depth_method: {depth_method!r} gives no distance map; use jointid_net")
            result = WaterOfImage(path, WaterInView.of(model.estimate(image, dist[0]), dist[0]))
        results.append(result)
        if on_image is not None:
            on_image(result)
    if json_out is not None:
        rows = [r.as_dict() for r in results if isinstance(r, WaterOfImage)]
        write_text_atomic(json_out, "".join(json.dumps(row) + "\n" for row in rows))
    return results
