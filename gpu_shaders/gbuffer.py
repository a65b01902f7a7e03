"""The G-buffer pass: the evaluated scene's meshes rasterised with gpu batches (glsl/gbuffer.glsl).

Mesh data and materials come from `operators.extract.extract_scene` (the same extraction the
bake uses). Every triangle is drawn with per-corner world positions and normals and its
material's values into one framebuffer with four RGBA32F colour attachments (MRT works on
llvmpipe) and a 32-bit float depth buffer:
    position (world xyz, w = coverage), normal (world), albedo (linear base colour),
    emission (colour x strength).
Albedo and emission are the material's *values*: image textures (Material.base_color_texture,
emission_texture) are not sampled yet (they would need a texture per material and a UV
attribute; extract already gives the per-corner UVs and the image arrays). Pixels are sampled
once at their centre (no anti-aliasing). Row 0 is the bottom row, as in Blender's render result.
Needs a GPU context (RenderEngine.render with bl_use_gpu_context).
"""
from __future__ import annotations

import time

import gpu
import numpy as np
from gpu_extras.batch import batch_for_shader

from .resources import glsl

ATTACHMENTS = ("position", "normal", "albedo", "emission")
_SHADER = {}


def gbuffer_shader():
    if "gbuffer" not in _SHADER:
        src = glsl("gbuffer.glsl")
        vert, frag = src.split("//FRAGMENT")
        iface = gpu.types.GPUStageInterfaceInfo("lumen_gbuffer_iface")
        iface.smooth('VEC3', "v_pos")
        iface.smooth('VEC3', "v_nor")
        iface.flat('VEC3', "v_albedo")
        iface.flat('VEC3', "v_emit")
        info = gpu.types.GPUShaderCreateInfo()
        info.push_constant('MAT4', "view_proj")
        for slot, name in enumerate(("pos", "nor", "albedo", "emit")):
            info.vertex_in(slot, 'VEC3', name)
        info.vertex_out(iface)
        for slot, name in enumerate(ATTACHMENTS):
            info.fragment_out(slot, 'VEC4', "out_" + name)
        info.vertex_source(vert)
        info.fragment_source(frag)
        _SHADER["gbuffer"] = gpu.shader.create_from_info(info)
    return _SHADER["gbuffer"]


def scene_triangles(objects):
    """numpy float32 arrays [3T, 3] (pos, nor, albedo, emit) of every triangle, in world space."""
    pos, nor, alb, emi = [], [], [], []
    for ob in objects:
        tris = np.asarray(ob.triangles, np.int64)
        if not len(tris):
            continue
        m = np.asarray(ob.matrix_world, np.float64)
        v = np.asarray(ob.vertices, np.float64) @ m[:3, :3].T + m[:3, 3]
        p = v[tris].reshape(-1, 3)
        normal_m = np.linalg.inv(m[:3, :3]).T
        if ob.normals is not None:
            n = np.asarray(ob.normals, np.float64).reshape(-1, 3) @ normal_m.T
        else:
            a, b, c = v[tris[:, 0]], v[tris[:, 1]], v[tris[:, 2]]
            n = np.repeat(np.cross(b - a, c - a), 3, axis=0)
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-20)
        if np.linalg.det(m[:3, :3]) < 0 and ob.normals is None:
            n = -n
        mats = list(ob.materials)
        t = len(tris)
        if mats:
            ids = (np.clip(np.asarray(ob.material_ids, np.int64), 0, len(mats) - 1)
                   if ob.material_ids is not None else np.zeros(t, np.int64))
            base = np.array([np.asarray(mt.base_color, np.float64)[:3] for mt in mats])
            emit = np.array([np.asarray(mt.emission_color, np.float64)[:3]
                             * float(mt.emission_strength) for mt in mats])
            a_t, e_t = base[ids], emit[ids]
        else:
            from ..lumen_addon.materials import Material
            a_t = np.tile(np.asarray(Material().base_color, np.float64)[:3], (t, 1))
            e_t = np.zeros((t, 3))
        pos.append(p)
        nor.append(n)
        alb.append(np.repeat(a_t, 3, axis=0))
        emi.append(np.repeat(e_t, 3, axis=0))
    if not pos:
        z = np.zeros((0, 3), np.float32)
        return z, z, z, z
    return tuple(np.concatenate(x).astype(np.float32) for x in (pos, nor, alb, emi))


def read_texture(tex, width, height):
    return np.asarray(tex.read().to_list(), np.float32).reshape(height, width, -1)


def render_gbuffer(objects, view_proj, width: int, height: int) -> dict:
    """Draw `objects` (ObjectInputs) with `view_proj` (4x4); returns {'textures': {name: GPUTexture},
    name: float32 [h, w, 4] for every attachment, 'depth': [h, w] window depth, timings}."""
    import mathutils

    t0 = time.perf_counter()
    shader = gbuffer_shader()
    pos, nor, alb, emi = scene_triangles(objects)
    textures = {name: gpu.types.GPUTexture((width, height), format='RGBA32F')
                for name in ATTACHMENTS}
    depth = gpu.types.GPUTexture((width, height), format='DEPTH_COMPONENT32F')
    fb = gpu.types.GPUFrameBuffer(depth_slot=depth,
                                  color_slots=tuple(textures[n] for n in ATTACHMENTS))
    t1 = time.perf_counter()
    with fb.bind():
        fb.clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
        if len(pos):
            batch = batch_for_shader(shader, 'TRIS', {"pos": pos, "nor": nor, "albedo": alb,
                                                      "emit": emi})
            gpu.state.depth_test_set('LESS_EQUAL')
            gpu.state.depth_mask_set(True)
            gpu.state.face_culling_set('NONE')
            gpu.state.viewport_set(0, 0, width, height)
            shader.bind()
            shader.uniform_float("view_proj", mathutils.Matrix(
                np.asarray(view_proj, np.float64).tolist()))
            batch.draw(shader)
            gpu.state.depth_test_set('NONE')
            gpu.state.depth_mask_set(False)
    out = {"textures": textures, "depth_texture": depth, "triangles": len(pos) // 3}
    for name in ATTACHMENTS:
        out[name] = read_texture(textures[name], width, height)
    out["depth"] = np.asarray(depth.read().to_list(), np.float32).reshape(height, width)
    out["draw_seconds"] = time.perf_counter() - t1
    out["seconds"] = time.perf_counter() - t0
    return out
