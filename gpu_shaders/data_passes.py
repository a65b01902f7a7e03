"""F12's data and emission passes, as Cycles writes them when View Layer > Passes enables them:

    Depth     (use_pass_z) the distance along the camera's view axis (Cycles' camera_z_depth),
              1e10 where no surface is
    Mist      (use_pass_mist) (distance - Start) / Depth of the world's Mist Pass settings,
              clamped to 0..1 and raised to the falloff (Quadratic 2, Linear 1, Inverse
              Quadratic 0.5); the distance along the ray for a perspective camera, along the
              view axis for an orthographic one; 1 where no surface is
    Position  (use_pass_position) the world position, 0 where no surface is
    Emission  (use_pass_emit) the surfaces' emission, 0 where no surface is

Before, Blender's compositor offered none of them for Lumen GI (a Depth socket for a depth of
field or fog node was missing). Computed in numpy from the G-buffer's pixel-centre position and
emission, read back once at the end of an F12 render (never per frame). bpy-free: render()
passes the camera's matrix and the mist settings.
"""
from __future__ import annotations

import numpy as np

# (View Layer property, pass name, channels, channel ids, type)
DATA_PASSES = (("use_pass_z", "Depth", 1, "Z", 'VALUE'),
               ("use_pass_mist", "Mist", 1, "Z", 'VALUE'),
               ("use_pass_position", "Position", 3, "XYZ", 'VECTOR'),
               ("use_pass_emit", "Emission", 3, "RGB", 'COLOR'))
NO_DEPTH = 1e10                       # Cycles' Depth where no surface is
FALLOFF = {'QUADRATIC': 2.0, 'LINEAR': 1.0, 'INVERSE_QUADRATIC': 0.5}


def shading_normal(position: np.ndarray, albedo: np.ndarray, emission: np.ndarray) -> np.ndarray:
    """float32 [h, w, 4]: the G-buffer's shading normal (a normal map's, else the interpolated
    normal), which gbuffer.glsl packs octahedrally into the albedo and emission w when a drawn
    mesh has a normal map (gbuffer_shading_lib.glsl decodes it the same way); 0 where no surface
    is. Cycles' Normal pass is the shading normal."""
    f = np.stack([albedo[..., 3], emission[..., 3]], -1).astype(np.float64) * 2.0 - 1.0
    n = np.concatenate([f, 1.0 - np.abs(f).sum(-1, keepdims=True)], -1)
    t = np.maximum(-n[..., 2:], 0.0)
    n[..., :2] -= np.where(n[..., :2] >= 0.0, 1.0, -1.0) * t
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-30)
    out = np.zeros(position.shape[:2] + (4,), np.float32)
    surface = position[..., 3] > 0.5
    out[..., :3] = np.where(surface[..., None], n, 0.0)
    out[..., 3] = 1.0
    return out


def wanted(view_layer) -> list:
    """The DATA_PASSES rows the view layer enables."""
    return [row for row in DATA_PASSES if bool(getattr(view_layer, row[0], False))]


def data_passes(names, position: np.ndarray, emission: np.ndarray, camera_matrix,
                orthographic: bool, mist=(5.0, 25.0, 'QUADRATIC')) -> dict:
    """{pass name: float32 [h, w, 4]} for `names` from the G-buffer's position (xyz, w > 0 on a
    surface) and emission, the camera's world matrix (it looks along its -Z) and the mist's
    (start, depth, falloff)."""
    position = np.asarray(position, np.float32)
    surface = position[..., 3] > 0.0
    m = np.asarray(camera_matrix, np.float64)
    origin, forward = m[:3, 3], -m[:3, 2] / max(np.linalg.norm(m[:3, 2]), 1e-300)
    rel = position[..., :3].astype(np.float64) - origin
    depth = rel @ forward
    out = {}
    for name in names:
        img = np.zeros(position.shape[:2] + (4,), np.float32)
        img[..., 3] = 1.0
        if name == "Depth":
            img[..., 0] = np.where(surface, depth, NO_DEPTH)
        elif name == "Mist":
            start, length, falloff = mist
            dist = depth if orthographic else np.linalg.norm(rel, axis=-1)
            t = np.clip((dist - float(start)) / max(float(length), 1e-9), 0.0, 1.0)
            t = t ** FALLOFF.get(falloff, 2.0)
            img[..., 0] = np.where(surface, t, 1.0)
        elif name == "Position":
            img[..., :3] = np.where(surface[..., None], position[..., :3], 0.0)
        elif name == "Emission":
            img[..., :3] = np.where(surface[..., None], np.asarray(emission)[..., :3], 0.0)
        out[name] = img
    return out
