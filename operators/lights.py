"""Blender lights -> plain float32 arrays for the preview engine (no gpu import).

`light_table(depsgraph)` returns one row of 16 float32 per visible light (4 RGBA texels of the
light texture read by glsl/direct_light.comp.glsl):

    texel 0: type (0 sun, 1 point, 2 spot, 3 area), world position xyz
    texel 1: world direction the light points (its -Z axis) xyz, radius (point/spot/area) or
             angular diameter in radians (sun)
    texel 2: colour x power in radiometric units (below) rgb, 1 if the light casts no shadow
             (Cast Shadow off, `use_shadow`: a fill light) else 0
    texel 3: spot cos(half cone angle), spot blend, area (m^2, area lights; for point and spot
             lights 1 with Soft Falloff, Blender's default, 0 without), an area light's
             tan(Spread / 2) (-1: 180 degrees, and for the other types; spread_of)

Units follow Cycles (intern/cycles/scene/light.cpp: point and spot strength x 1/(4 pi), area
x 1/pi, or x area / pi with Normalize off, sun unchanged; the colour times the Temperature's
blackbody colour and 2^Exposure: light_colour), so that irradiance E at a surface point, and
Cycles' Diffuse Direct pass (E / pi for a Lambert BSDF, the albedo left out), come out the same:
    sun:   colour x strength = irradiance E (W/m^2) on a surface facing it
    point: colour x P / (4 pi) = radiant intensity I (W/sr); E = I cos / d^2
    spot:  the same as point, times Cycles' spot mask smoothstep((cos - cos_half) / (blend (1 - cos_half)))
    area:  approximated as a one-sided small emitter at its centre: colour x P / pi = on-axis
           intensity I0 (W/sr), I = I0 max(cos_light, 0) (P = L A pi for a Lambertian emitter)

The world is not a row here: operators/world_capture.py turns it into radiance maps (and a sun
row for a bright HDRI spot).
"""
from __future__ import annotations

import math

import numpy as np

LIGHT_TYPES = {"SUN": 0, "POINT": 1, "SPOT": 2, "AREA": 3}
ROW = 16


def _area_size(light):
    sx = float(light.size)
    sy = float(light.size_y) if light.shape in {"RECTANGLE", "ELLIPSE"} else sx
    area = sx * sy
    if light.shape in {"DISK", "ELLIPSE"}:
        area *= math.pi / 4.0
    return area, 0.5 * math.sqrt(sx * sx + sy * sy)


def light_colour(light) -> np.ndarray:
    """The light's colour as Cycles multiplies it into the strength: Color, times the
    blackbody colour of its Temperature when Use Temperature is on, times 2^Exposure (Blender
    4.x+ lights; absent properties leave it alone)."""
    colour = np.asarray(light.color, np.float64)[:3].copy()
    if getattr(light, "use_temperature", False):
        colour *= np.asarray(light.temperature_color, np.float64)[:3]
    return colour * 2.0 ** float(getattr(light, "exposure", 0.0))


def spread_of(light):
    """(tan of half the Spread, or -1 for a full 180 degrees; the gain that keeps the power)
    of an area light. Cycles fans a gridded softbox's light as (1 - tan(a) / tan(s / 2)) at an
    angle a off its axis, scaled to keep its power: the cosine-weighted integral of that over
    the hemisphere is pi (1 - atan(t) / t) for t = tan(s / 2), against pi unfanned
    (light_lib.glsl reads the tangent; measured against Cycles' floor under 90 and 60 degree
    spreads: gains 4.4-4.6 and 9.8-10.5 against these 4.66 and 10.74)."""
    spread = float(getattr(light, "spread", math.pi))
    if spread >= math.pi - 1e-6:
        return -1.0, 1.0
    t = max(math.tan(0.5 * max(spread, 0.0)), 1e-4)
    return t, 1.0 / max(1.0 - math.atan(t) / t, 1e-12)


def light_row(light, matrix_world) -> np.ndarray:
    """The 16 float32 of one bpy Light datablock placed by `matrix_world` (4x4)."""
    m = np.asarray(matrix_world, np.float64)
    pos = m[:3, 3]
    direction = -m[:3, 2]
    direction = direction / max(np.linalg.norm(direction), 1e-12)
    colour = light_colour(light)
    row = np.zeros(ROW, np.float32)
    kind = LIGHT_TYPES[light.type]
    row[0] = kind
    row[1:4] = pos
    row[4:7] = direction
    cos_half = blend = area = 0.0
    if kind == 0:
        row[7] = float(light.angle)
        row[8:11] = colour * float(light.energy)
    elif kind in (1, 2):
        row[7] = float(light.shadow_soft_size)
        row[8:11] = colour * float(light.energy) / (4.0 * math.pi)
        if kind == 2:
            cos_half = math.cos(0.5 * float(light.spot_size))
            blend = float(light.spot_blend)
        area = 1.0 if getattr(light, "use_soft_falloff", True) else 0.0
    else:
        area, radius = _area_size(light)
        row[7] = radius
        # Normalize off: the strength is per square metre of the light (Cycles' invarea 1)
        per_area = 1.0 if getattr(light, "normalize", True) else area
        row[8:11] = colour * float(light.energy) * per_area / math.pi
        tan_half, gain = spread_of(light)
        row[8:11] *= gain
        row[15] = tan_half
    row[11] = 0.0 if getattr(light, "use_shadow", True) else 1.0
    row[12:15] = (cos_half, blend, area)
    if kind != 3:
        row[15] = -1.0
    return row


def light_table(depsgraph) -> np.ndarray:
    """float32 [N, 16]: every light instance of the evaluated depsgraph (see the module doc)."""
    rows = []
    view_layer = depsgraph.view_layer
    # F12's depsgraph holds what renders: a light hidden in the viewport only lights F12, as in
    # Cycles (visible_get is the viewport's visibility)
    rendering = getattr(depsgraph, "mode", "VIEWPORT") == 'RENDER'
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type != 'LIGHT' or obj.data.type not in LIGHT_TYPES:
            continue
        if not (inst.is_instance or rendering) \
                and not obj.original.visible_get(view_layer=view_layer):
            continue
        if not getattr(obj.original, "visible_diffuse", True):
            continue          # Ray Visibility > Diffuse off: in Cycles it lights no diffuse
                              # surface, directly or by bounces, and diffuse is all we shade
        rows.append(light_row(obj.data, inst.matrix_world))
    return np.array(rows, np.float32).reshape(-1, ROW)
