"""The G-buffer pass: the evaluated scene's meshes rasterised with gpu batches (glsl/gbuffer.glsl).

Mesh data and materials come from `operators.extract` (the same extraction the bake uses). The
engine's frame draws through mesh_batches.py (local-space batches per unique mesh kept on the GPU,
instanced with a matrix table; its vertex stage glsl/gbuffer_instanced.glsl, its fragment stage
this file's); `render_gbuffer` below, which builds world-space corners in numpy on every call, is
what RSM's light-view maps still use. Every triangle is drawn with per-corner normals and its
material's values into one framebuffer with four RGBA32F colour attachments (MRT works on
llvmpipe) and a 32-bit float depth buffer:
    position (world xyz, w = coverage), normal (world), albedo (linear base colour),
    emission (colour x strength).
Albedo and emission use the material's image textures (Material.base_color_texture,
emission_texture) when there is one and the mesh has UVs, else its values; triangles are drawn
in one batch per (albedo texture, emission texture) pair with per-corner UVs, each texture array
uploaded once per frame (RGBA32F, cached by id(array)) and filtered in the shader like
materials.sample_texture (bilinear, wrapping). Pixels are sampled
once at their centre (no anti-aliasing). Row 0 is the bottom row, as in Blender's render result.
Needs a GPU context (RenderEngine.render with bl_use_gpu_context).
"""
from __future__ import annotations

import time

import gpu
import numpy as np
from gpu_extras.batch import batch_for_shader

from . import resources
from .packing import singular
from .resources import glsl

ATTACHMENTS = ("position", "normal", "albedo", "emission")
# per-corner vertex inputs: tan is the MikkTSpace tangent xyz and the bitangent's sign (zero
# without a normal map)
VERTEX_INPUTS = (("pos", 'VEC3'), ("nor", 'VEC3'), ("uv", 'VEC2'), ("albedo", 'VEC3'),
                 ("emit", 'VEC3'), ("tan", 'VEC4'))
ATTRIBUTES = tuple(name for name, _ in VERTEX_INPUTS)
# what a draw group binds (textures, flags) besides its vertex inputs
MATERIAL_KEYS = ("albedo_tex", "emit_tex", "alpha_clip", "normal_tex", "normal_strength", "bump",
                 "holdout")
_SHADER = {}


def gbuffer_program(key: str, vertex_source: str, instanced: bool = False):
    """A G-buffer shader: gbuffer.glsl's fragment stage (the four attachments, material textures)
    after `vertex_source`. instanced: the vertex stage reads its instance's matrices from the
    `instances` texture at row instance_base + gl_InstanceID (mesh_batches.py). One declaration
    for both, so the two vertex stages cannot drift apart from the fragment stage."""
    if key not in _SHADER:
        frag = glsl("gbuffer.glsl").split("//FRAGMENT")[1]
        iface = gpu.types.GPUStageInterfaceInfo(f"lumen_{key}_iface")
        iface.smooth('VEC3', "v_pos")
        iface.smooth('VEC3', "v_nor")
        iface.smooth('VEC2', "v_uv")
        iface.smooth('VEC4', "v_tan")
        iface.flat('VEC3', "v_albedo")
        iface.flat('VEC3', "v_emit")
        iface.flat('FLOAT', "v_holdout")
        info = gpu.types.GPUShaderCreateInfo()
        info.push_constant('MAT4', "view_proj")
        if instanced:
            info.push_constant('INT', "instance_base")
        info.push_constant('INT', "use_albedo_tex")
        info.push_constant('INT', "alpha_clip")
        info.push_constant('INT', "use_emit_tex")
        info.push_constant('INT', "albedo_base_h")
        info.push_constant('INT', "emit_base_h")
        info.push_constant('INT', "use_normal_tex")
        info.push_constant('INT', "normal_base_h")
        info.push_constant('FLOAT', "normal_strength")
        info.push_constant('INT', "pack_shading")
        info.push_constant('INT', "group_holdout")
        info.push_constant('FLOAT', "footprint_scale")
        info.sampler(0, 'FLOAT_2D', "albedo_tex")
        info.sampler(1, 'FLOAT_2D', "emit_tex")
        info.sampler(2, 'FLOAT_2D', "normal_tex")
        if instanced:
            info.sampler(3, 'FLOAT_2D', "instances")
        for slot, (name, kind) in enumerate(VERTEX_INPUTS):
            info.vertex_in(slot, kind, name)
        info.vertex_out(iface)
        for slot, name in enumerate(ATTACHMENTS):
            info.fragment_out(slot, 'VEC4', "out_" + name)
        info.vertex_source(vertex_source)
        info.fragment_source(frag)
        _SHADER[key] = gpu.shader.create_from_info(info)
    return _SHADER[key]


def normal_mode(g) -> int:
    """gbuffer.glsl's use_normal_tex of a draw group: 0 none, 1 a tangent-space normal map, 2 a
    Bump node's height."""
    return 0 if g["normal_tex"] is None else (2 if g.get("bump") else 1)


def gbuffer_shader():
    """World-space corners (render_gbuffer: the RSMs' light views, tests)."""
    return gbuffer_program("gbuffer", glsl("gbuffer.glsl").split("//FRAGMENT")[0])


def texture_rgba(tex) -> np.ndarray:
    """A material texture array (H, W) or (H, W, C) as float32 (H, W, 4) RGBA, channels as
    materials.sample_texture reads them (one channel: grey; three or more: the first three)."""
    t = np.asarray(tex, np.float32)
    if t.ndim == 2:
        t = t[:, :, None]
    h, w, c = t.shape
    out = np.ones((h, w, 4), np.float32)
    out[..., :3] = t[..., :3] if c >= 3 else t[..., :1]
    if c == 4:
        out[..., 3] = t[..., 3]           # a cut-out's alpha (Material.alpha_clip)
    return out


def mip_chain(rgba: np.ndarray) -> np.ndarray:
    """The texture's mip levels stacked in rows (level 0 first, each a 2x2 box average of the one
    before, down to one texel per side; width W, height the sum of the levels' heights; levels
    narrower than W use their first columns). The G-buffer picks a level per pixel from the UV
    footprint (gbuffer.glsl sample_mipmapped): one sample of level 0 per pixel aliased a brick
    texture seen at a distance into moire (relMSE 0.057 against EEVEE's 0.038 on the `textured`
    benchmark scene), and Blender 5.0 cannot turn on hardware mipmaps from Python."""
    levels = [np.asarray(rgba, np.float32)]
    while max(levels[-1].shape[:2]) > 1:
        a = levels[-1]
        h, w = a.shape[:2]
        h2, w2 = max(h // 2, 1), max(w // 2, 1)
        a = a[:h2 * 2 if h > 1 else 1, :w2 * 2 if w > 1 else 1]
        a = a.reshape(h2, -1, w2, a.shape[1] // w2, 4).mean(axis=(1, 3))
        levels.append(a.astype(np.float32))
    h0, w0 = levels[0].shape[:2]
    out = np.zeros((sum(a.shape[0] for a in levels), w0, 4), np.float32)
    y = 0
    for a in levels:
        out[y:y + a.shape[0], :a.shape[1]] = a
        y += a.shape[0]
    return out


def upload_texture(tex):
    """(RGBA32F 2D GPUTexture of a material texture's mip chain (mip_chain; row 0 = v 0), the
    base level's height)."""
    rgba = texture_rgba(tex)
    chain = mip_chain(rgba)
    buf = gpu.types.Buffer('FLOAT', chain.size, chain.ravel())
    return gpu.types.GPUTexture((chain.shape[1], chain.shape[0]), format='RGBA32F',
                                data=buf), rgba.shape[0]


def scene_triangles(objects):
    """Draw groups of every triangle, in world space: a list of dicts with numpy float32 arrays
    pos, nor, albedo, emit [3T, 3], uv [3T, 2] and the texture arrays albedo_tex / emit_tex (or
    None) that the group's fragments sample. Triangles are grouped by (albedo texture, emission
    texture) identity; untextured triangles all go to one group. With an emission texture the
    per-corner emit value is the strength (the shader multiplies), as materials.shade does. A
    vertex_colors material's per-corner albedo is the object's `colors`."""
    groups = {}
    for ob in objects:
        tris = np.asarray(ob.triangles, np.int64)
        if not len(tris) or not getattr(ob, "camera_visible", True):
            continue          # invisible to the camera: in the SDF and cards, not in the image
        m = np.asarray(ob.matrix_world, np.float64)
        if singular(m):
            continue          # scaled to 0 (or not finite): Blender draws nothing of it either
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
        t = len(tris)
        uvs = getattr(ob, "uvs", None)
        uv = (np.asarray(uvs, np.float64).reshape(-1, 2) if uvs is not None
              else np.zeros((3 * t, 2)))
        colors = getattr(ob, "colors", None)            # (T, 3, 3): Material.vertex_colors
        colors = np.asarray(colors, np.float64) if colors is not None else None
        tangents = getattr(ob, "tangents", None)        # (T, 3, 4): normal maps
        if tangents is not None:
            tangents = np.asarray(tangents, np.float64).reshape(-1, 4).copy()
            tangents[:, :3] = tangents[:, :3] @ m[:3, :3].T     # world space, as the positions
        from ..lumen_addon.materials import Material
        mats = list(ob.materials) or [Material()]
        ids = (np.clip(np.asarray(ob.material_ids, np.int64), 0, len(mats) - 1)
               if ob.material_ids is not None and len(mats) > 1 else np.zeros(t, np.int64))
        for k, mt in enumerate(mats):
            sel = np.flatnonzero(ids == k)
            if not sel.size:
                continue
            vertex = colors is not None and getattr(mt, "vertex_colors", False)
            a_tex = mt.base_color_texture if uvs is not None and not vertex else None
            e_tex = (mt.emission_texture if uvs is not None and mt.emission_strength
                     else None)
            alb = np.asarray(mt.base_color, np.float64)[:3]
            if e_tex is not None:
                emi = np.full(3, float(mt.emission_strength))
            else:
                emi = np.asarray(mt.emission_color, np.float64)[:3] * float(mt.emission_strength)
            clip = bool(getattr(mt, "alpha_clip", False)) and a_tex is not None
            n_tex = getattr(mt, "normal_texture", None)
            bump = bool(getattr(mt, "bump", False))      # a height: no tangents needed
            n_tex = n_tex if uvs is not None and (bump or tangents is not None) else None
            strength = float(getattr(mt, "normal_strength", 1.0))
            key = (id(a_tex) if a_tex is not None else None,
                   id(e_tex) if e_tex is not None else None, clip,
                   id(n_tex) if n_tex is not None else None, strength if n_tex is not None else 0,
                   bump, bool(getattr(mt, "holdout", False)))
            g = groups.setdefault(key, dict(albedo_tex=a_tex, emit_tex=e_tex, alpha_clip=clip,
                                            normal_tex=n_tex, normal_strength=strength,
                                            bump=bump, holdout=key[-1], tan=[],
                                            pos=[], nor=[],
                                            uv=[], albedo=[], emit=[]))
            corners = (sel[:, None] * 3 + np.arange(3)).ravel()
            g["pos"].append(p[corners])
            g["nor"].append(n[corners])
            g["tan"].append(tangents[corners] if tangents is not None
                            else np.zeros((len(corners), 4)))
            g["uv"].append(uv[corners])
            g["albedo"].append(colors[sel].reshape(-1, 3) if vertex
                               else np.tile(alb, (len(corners), 1)))
            g["emit"].append(np.tile(emi, (len(corners), 1)))
    out = []
    for g in groups.values():
        for name in ATTRIBUTES:
            g[name] = np.concatenate(g[name]).astype(np.float32)
        out.append(g)
    return out


def read_texture(tex, width, height):
    return resources.read_texture(tex, (height, width, -1))


def render_gbuffer(objects, view_proj, width: int, height: int, texture_cache=None) -> dict:
    """Draw `objects` (ObjectInputs) with `view_proj` (4x4); returns {'textures': {name: GPUTexture},
    'depth_texture', counts, timings}: nothing is read back (read_texture does, on request).
    `texture_cache` ({id(array): (array, (GPUTexture, base height))}) keeps material
    texture uploads across frames; entries whose array is not drawn this frame are dropped."""
    import mathutils

    t0 = time.perf_counter()
    shader = gbuffer_shader()
    groups = scene_triangles(objects)
    cache = texture_cache if texture_cache is not None else {}
    used, uploaded = set(), 0
    dummy = None

    def gpu_texture(arr):
        nonlocal uploaded
        key = id(arr)
        used.add(key)
        hit = cache.get(key)
        if hit is None or hit[0] is not arr:      # the array is kept alive: ids stay unique
            cache[key] = hit = (arr, upload_texture(arr))
            uploaded += 1
        return hit[1]

    textures = {name: gpu.types.GPUTexture((width, height), format='RGBA32F')
                for name in ATTACHMENTS}
    depth = gpu.types.GPUTexture((width, height), format='DEPTH_COMPONENT32F')
    fb = gpu.types.GPUFrameBuffer(depth_slot=depth,
                                  color_slots=tuple(textures[n] for n in ATTACHMENTS))
    t1 = time.perf_counter()
    triangles = 0
    with fb.bind():
        fb.clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
        gpu.state.depth_test_set('LESS_EQUAL')
        gpu.state.depth_mask_set(True)
        gpu.state.face_culling_set('NONE')
        gpu.state.viewport_set(0, 0, width, height)
        shader.bind()
        shader.uniform_float("view_proj", mathutils.Matrix(
            np.asarray(view_proj, np.float64).tolist()))
        shader.uniform_float("footprint_scale", 1.0)
        packed = any(g["normal_tex"] is not None for g in groups)
        shader.uniform_int("pack_shading", int(packed))
        for g in groups:
            if not len(g["pos"]):
                continue
            triangles += len(g["pos"]) // 3
            if dummy is None and (g["albedo_tex"] is None or g["emit_tex"] is None
                                  or g["normal_tex"] is None):
                dummy = gpu.types.GPUTexture((1, 1), format='RGBA32F', data=gpu.types.Buffer(
                    'FLOAT', 4, [1.0, 1.0, 1.0, 1.0]))
            a_tex, a_h = gpu_texture(g["albedo_tex"]) if g["albedo_tex"] is not None else (dummy, 1)
            e_tex, e_h = gpu_texture(g["emit_tex"]) if g["emit_tex"] is not None else (dummy, 1)
            n_tex, n_h = (gpu_texture(g["normal_tex"]) if g["normal_tex"] is not None
                          else (dummy, 1))
            batch = batch_for_shader(shader, 'TRIS', {name: g[name] for name in ATTRIBUTES})
            shader.bind()
            shader.uniform_int("use_albedo_tex", int(g["albedo_tex"] is not None))
            shader.uniform_int("alpha_clip", int(g["alpha_clip"]))
            shader.uniform_int("use_emit_tex", int(g["emit_tex"] is not None))
            shader.uniform_int("albedo_base_h", int(a_h))
            shader.uniform_int("emit_base_h", int(e_h))
            shader.uniform_sampler("albedo_tex", a_tex)
            shader.uniform_sampler("emit_tex", e_tex)
            shader.uniform_int("use_normal_tex", normal_mode(g))
            shader.uniform_int("group_holdout", int(g["holdout"]))
            shader.uniform_int("normal_base_h", int(n_h))
            shader.uniform_float("normal_strength", float(g["normal_strength"]))
            shader.uniform_sampler("normal_tex", n_tex)
            batch.draw(shader)
        gpu.state.depth_test_set('NONE')
        gpu.state.depth_mask_set(False)
    for key in [k for k in cache if k not in used]:
        del cache[key]
    out = {"textures": textures, "depth_texture": depth, "triangles": triangles,
           "shading_normals": bool(packed),
           "draws": sum(1 for g in groups if len(g["pos"])), "texture_uploads": uploaded,
           "textures_resident": len(cache)}
    out["draw_seconds"] = time.perf_counter() - t1
    out["seconds"] = time.perf_counter() - t0
    return out
