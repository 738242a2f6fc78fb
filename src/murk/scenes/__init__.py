"""Procedural underwater construction-site scenes: clean RGB + exact line-of-sight distance.

Sample, then render (DESIGN.md rule 3)::

    from murk.scenes import sample_scene, render_scene
    params = sample_scene(seed, SceneConfig())        # frozen, JSON-serialisable (params.to_dict())
    rgb, dist_m = render_scene(params, (640, 480))     # float32 (H, W, 3) in [0, 1], float32 (H, W) metres

``dist_m`` is the distance from the camera centre along each pixel's ray (what Eq. (1) of the paper needs),
not the z-depth. ``render_scenes_torch`` renders a batch on CPU or CUDA with the same kernels.
"""

from murk.scenes.config import LAYOUTS, Layout, SceneConfig
from murk.scenes.params import (
    SCENE_FORMAT_VERSION,
    Box,
    Camera,
    Frustum,
    Lighting,
    Material,
    Net,
    SceneObject,
    SceneParams,
    Seabed,
    Sphere,
    Wave,
    scene_from_dict,
)
from murk.scenes.render import intrinsics, render_scene, render_scenes_torch
from murk.scenes.sample import sample_scene, seabed_height
from murk.scenes.textures import IMAGE_TEXTURE_PX, prepare_image_texture

__all__ = [
    "IMAGE_TEXTURE_PX",
    "LAYOUTS",
    "SCENE_FORMAT_VERSION",
    "Box",
    "Camera",
    "Frustum",
    "Layout",
    "Lighting",
    "Material",
    "Net",
    "SceneConfig",
    "SceneObject",
    "SceneParams",
    "Seabed",
    "Sphere",
    "Wave",
    "intrinsics",
    "prepare_image_texture",
    "render_scene",
    "render_scenes_torch",
    "sample_scene",
    "scene_from_dict",
    "seabed_height",
]
