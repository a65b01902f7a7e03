"""Light propagation volumes (lecture 21, "Light Propagation Volumes (LPV)", CryEngine 3;
Kaplanyan and Dachsbacher 2010): GI Method LPV, the lights' first bounce carried through a grid.

Per frame:
    rsm.render_maps   the lights' reflective shadow maps (rsm.py: position, normal, flux per
                      texel), the virtual point lights
    lpv_inject        one point per RSM texel drawn with additive blending into the grid: 2-band
                      SH (4 coefficients per colour channel) of each cell's summed intensity
    lpv_geometry      per cell, the transmittance of its +x, +y, +z crossings from the mesh SDFs
                      (re-made only when the grid or the objects change)
    lpv_propagate     `iterations` times: each cell gathers from its six neighbours through the
                      faces of its own cell (the face-based scheme), summed into the accumulated
                      volume
    lpv_gather        per pixel, the accumulated SH trilinearly half a cell in front of the
                      surface, convolved with the cosine lobe of its normal: E_indirect
Why one grid fitted to the scene's bounds (cubic cells, `cells` along the longest side, fewer
along the others) rather than 32^3 around the camera: the RSMs are fitted to the same bounds, so
every virtual light lands in a cell and none of the bounce is lost, and light from behind the
camera still propagates into view; the price is coarser cells in large scenes (no cascades).
Light moves one cell per iteration, so `iterations` should be about twice `cells` for it to cross
the grid (the defaults, 24 and 48, were the best of 16..32 cells on bench/quality.py's Cornell
box and sunlit room). The propagation is linear (the accumulated volume holds exactly
(iterations + 1) x the injected flux when nothing leaves the grid: tests/gpu/test_lpv.py), so
nothing is clamped before the per-pixel lookup; 2-band SH cannot hold the zero of a cosine lobe
at grazing angles, so a lit floor's light spreads along it and is read back by it
(self-illumination: 0.6 of its exitance in the test) and light wraps around thin walls' edges.
Emission does not inject (an emissive surface is no light of the RSMs, as with GI Method RSM), and
the light bounces once (the propagated light does not re-inject). Needs a GPU context.
"""
from __future__ import annotations

import gpu
import numpy as np
from gpu_extras.batch import batch_for_shader

from . import compute
from .resources import glsl
from .rsm import RSM, scene_bounds

GRID = ("r", "g", "b")          # one RGBA32F texture per colour channel: its 4 SH coefficients
_SHADERS = {}
_BATCHES = {}


def fit_grid(lo, hi, cells: int):
    """(origin [3], cell side h, dims [3] ints) of the grid over the bounds lo..hi: cubic cells,
    `cells` along the longest side with one cell of margin at each end (a surface's virtual
    light is shifted half a cell along its normal), as many as the bounds need along the others."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    cells = max(int(cells), 4)
    extent = np.maximum(hi - lo, 1e-3)
    h = float(extent.max()) / (cells - 2)
    dims = np.clip(np.ceil(extent / h - 1e-9).astype(int) + 2, 2, cells)
    origin = 0.5 * (lo + hi) - 0.5 * h * dims
    return origin, h, tuple(int(d) for d in dims)


def grid_size(dims):
    """(width, height) of the 2D textures holding a grid (lpv_lib.glsl's layout)."""
    return int(dims[0]), int(dims[1]) * int(dims[2])


def new_grid(dims) -> dict:
    return {c: compute.texture(grid_size(dims)) for c in GRID}


def _grid_push(sh, origin, h, dims, with_origin=True):
    if with_origin:
        sh.uniform_float("grid_origin", grid_origin(origin, h))
    sh.uniform_int("grid_dims", grid_dims(dims))


def grid_origin(origin, h) -> tuple:
    """lpv_lib.glsl's grid_origin: xyz the grid's corner, w the cell size."""
    return (*compute.vec(origin), float(h))


def grid_dims(dims) -> tuple:
    return (int(dims[0]), int(dims[1]), int(dims[2]), 0)


GRID_PUSH = (('VEC4', 'grid_origin'), ('IVEC4', 'grid_dims'))
GEOMETRY = compute.Pass("lpv_geometry", push=GRID_PUSH)
PROPAGATE = compute.Pass("lpv_propagate", samplers=("src_r", "src_g", "src_b", "geometry"),
                         images=tuple(("out_" + c) for c in GRID) + tuple(
                             ("acc_" + c, 'RGBA32F', {'READ', 'WRITE'}) for c in GRID),
                         push=(('IVEC4', 'grid_dims'), ('INT', 'first')))
GATHER = compute.Pass("lpv_gather",
                      samplers=("gbuf_position", "gbuf_normal", "acc_r", "acc_g", "acc_b"),
                      push=GRID_PUSH + (('VEC3', 'cam_pos'),))


def _inject_shader():
    if "inject" not in _SHADERS:
        vert, frag = glsl("lpv_inject.glsl").split("//FRAGMENT")
        iface = gpu.types.GPUStageInterfaceInfo("lumen_lpv_inject_iface")
        for c in GRID:
            iface.flat('VEC4', "v_" + c)
        info = gpu.types.GPUShaderCreateInfo()
        info.push_constant('VEC4', "grid_origin")
        info.push_constant('IVEC4', "grid_dims")
        info.push_constant('INT', "rsm_res")
        for slot, name in enumerate(("rsm_position", "rsm_normal", "rsm_flux")):
            info.sampler(slot, 'FLOAT_2D', name)
        info.vertex_in(0, 'FLOAT', "idx")
        info.vertex_out(iface)
        for slot, c in enumerate(GRID):
            info.fragment_out(slot, 'VEC4', "out_" + c)
        info.vertex_source(vert)
        info.fragment_source(frag)
        _SHADERS["inject"] = gpu.shader.create_from_info(info)
    return _SHADERS["inject"]


def inject(maps, origin, h, dims, grid: dict):
    """Clear `grid` and add every map's texels into it (maps: RSM.maps; one draw per map)."""
    sh = _inject_shader()
    fb = gpu.types.GPUFrameBuffer(color_slots=tuple(grid[c] for c in GRID))
    w, hh = grid_size(dims)
    with fb.bind():
        fb.clear(color=(0.0, 0.0, 0.0, 0.0))
        gpu.state.depth_test_set('NONE')
        gpu.state.face_culling_set('NONE')
        gpu.state.blend_set('ADDITIVE_PREMULT')
        gpu.state.program_point_size_set(True)
        gpu.state.viewport_set(0, 0, w, hh)
        sh.bind()
        for m in maps:
            t = m["textures"]
            res = int(t["flux"].width)
            batch = _BATCHES.get(res)
            if batch is None:
                batch = _BATCHES[res] = batch_for_shader(
                    sh, 'POINTS', {"idx": np.arange(res * res, dtype=np.float32)})
            sh.uniform_sampler("rsm_position", t["position"])
            sh.uniform_sampler("rsm_normal", t["normal"])
            sh.uniform_sampler("rsm_flux", t["flux"])
            _grid_push(sh, origin, h, dims)
            sh.uniform_int("rsm_res", res)
            batch.draw(sh)
        gpu.state.blend_set('NONE')
        gpu.state.program_point_size_set(False)
    return grid


def geometry(resources, origin, h, dims, occlusion: bool = True):
    """The transmittance of each cell's +x, +y, +z crossing (RGBA32F, rgb): from the mesh SDFs,
    or 1 everywhere without occlusion (or without objects)."""
    size = grid_size(dims)
    if not occlusion or resources is None:
        tex = compute.texture(size)
        tex.clear(format='FLOAT', value=(1.0, 1.0, 1.0, 1.0))
        return tex
    out = compute.texture(size)
    GEOMETRY.run(size, scene=resources, grid_origin=grid_origin(origin, h),
                 grid_dims=grid_dims(dims), out_image=out)
    return out


def propagate(src: dict, geometry_tex, dims, iterations: int, work=None):
    """`iterations` propagation steps from the grid `src` (the injected light; left as it is).
    Returns (accumulated = src + every step, the last step's light, the textures used: pass them
    back as `work` to reuse them)."""
    size = grid_size(dims)
    work = work or {}
    ping = work.get("ping") or new_grid(dims)
    pong = work.get("pong") or new_grid(dims)
    acc = work.get("acc") or new_grid(dims)
    if iterations <= 0:
        return src, src, dict(ping=ping, pong=pong, acc=acc)
    cur, nxt = src, ping
    for k in range(int(iterations)):
        PROPAGATE.run(size, **{"src_" + c: cur[c] for c in GRID},
                      **{"out_" + c: nxt[c] for c in GRID}, **{"acc_" + c: acc[c] for c in GRID},
                      geometry=geometry_tex, grid_dims=grid_dims(dims), first=int(k == 0))
        cur, nxt = nxt, (pong if nxt is ping else ping)
    return acc, cur, dict(ping=ping, pong=pong, acc=acc)


def gather(gbuf: dict, acc: dict, origin, h, dims, cam_pos, width: int, height: int):
    """E_indirect per pixel from the accumulated grid (RGBA32F texture)."""
    out = compute.texture((width, height))
    g = gbuf["textures"]
    GATHER.run((width, height), gbuf_position=g["position"], gbuf_normal=g["normal"],
               **{"acc_" + c: acc[c] for c in GRID}, grid_origin=grid_origin(origin, h),
               grid_dims=grid_dims(dims), cam_pos=compute.vec(cam_pos), out_image=out)
    return out


def read_grid(grid: dict, dims) -> np.ndarray:
    """float32 [3 (rgb), nz, ny, nx, 4 (SH)] of a grid (waits for the GPU; tests, debug view)."""
    nx, ny, nz = dims
    return np.stack([compute.read(grid[c]).reshape(nz, ny, nx, 4) for c in GRID])


def total_flux(sh: np.ndarray) -> np.ndarray:
    """Total flux (rgb) of a grid read by read_grid: sum of 2 sqrt(pi) c0 over the cells."""
    return 2.0 * np.sqrt(np.pi) * sh[..., 0].reshape(3, -1).sum(-1, dtype=np.float64)


class LPV:
    """The LPV of the last frame: its RSMs, grid textures and E_indirect (on the SceneState)."""

    def __init__(self, width: int, height: int):
        self.width, self.height = int(width), int(height)
        self.rsm = RSM(width, height)
        self.grid = None             # (origin, h, dims)
        self.injected = None         # the injected grid's textures
        self.work = {}               # ping, pong, acc
        self.acc = None
        self.geometry, self.geometry_key = None, None
        self.history = None          # E_indirect
        self.frames = 0
        self.key = None

    def reset(self):
        self.history, self.frames = None, 0

    def update(self, objects, state, cells: int, iterations: int, occlusion: bool,
               rsm_resolution: int, objects_changed: bool):
        """RSMs, injection, geometry (when the grid or the objects changed) and propagation."""
        self.rsm.render_maps(objects, state.lights, state.light_texture, rsm_resolution)
        lo, hi = scene_bounds(objects)
        origin, h, dims = fit_grid(lo, hi, cells)
        if self.grid is None or self.grid[2] != dims:
            self.injected, self.work, self.geometry = new_grid(dims), {}, None
        self.grid = (origin, h, dims)
        inject(self.rsm.maps, origin, h, dims, self.injected)
        key = (origin.tobytes(), h, dims, bool(occlusion), id(state.resources))
        if self.geometry is None or key != self.geometry_key or objects_changed:
            self.geometry = geometry(state.resources, origin, h, dims, occlusion)
            self.geometry_key = key
        self.acc, _, self.work = propagate(self.injected, self.geometry, dims, iterations,
                                           self.work)

    def iterate(self, gbuf: dict, cam_pos):
        origin, h, dims = self.grid
        self.history = gather(gbuf, self.acc, origin, h, dims, cam_pos, self.width, self.height)
        self.frames = 1
        return self.history

    def grid_image(self, width: int, height: int) -> np.ndarray:
        """The LPV_GRID debug view (reads the grid back): the accumulated volume's horizontal
        slices side by side (bottom slice at the top left, rows of slices downwards, +y up in
        each), each cell as the mean radiance of its light, 2 sqrt(pi) c0 / (4 pi h^2), stretched
        over the image; black before the first frame."""
        out = np.zeros((height, width, 4), np.float32)
        out[..., 3] = 1.0
        if self.acc is None:
            return out
        origin, h, dims = self.grid
        nx, ny, nz = dims
        sh = read_grid(self.acc, dims)
        mean = np.moveaxis(sh[..., 0], 0, -1) * (2.0 * np.sqrt(np.pi) / (4.0 * np.pi * h * h))
        cols = int(np.ceil(np.sqrt(nz)))
        rows = -(-nz // cols)
        atlas = np.zeros((rows * ny, cols * nx, 3), np.float32)
        for z in range(nz):             # a few dozen slices, debug view only
            r, c = divmod(z, cols)
            atlas[r * ny:(r + 1) * ny, c * nx:(c + 1) * nx] = mean[z][::-1]
        atlas = np.maximum(atlas, 0.0)[::-1]          # row 0 of the image is its bottom
        ys = np.minimum((np.arange(height) * atlas.shape[0]) // height, atlas.shape[0] - 1)
        xs = np.minimum((np.arange(width) * atlas.shape[1]) // width, atlas.shape[1] - 1)
        out[..., :3] = atlas[ys][:, xs]
        return out

    def stats(self) -> dict:
        """GPU bytes: the RSMs (lpv_rsm_*), the injected grid, the propagation's two grids, the
        accumulated grid, the geometry (transmittance) grid, E_indirect."""
        out = {"lpv_" + k: v for k, v in self.rsm.stats().items() if k != "rsm_history"}
        if self.grid is not None:
            one = int(np.prod(self.grid[2])) * 16
            out["lpv_injected"] = 3 * one
            out["lpv_propagation"] = 6 * one
            out["lpv_accumulated"] = 3 * one
            if self.geometry is not None:
                out["lpv_geometry"] = one
        if self.history is not None:
            out["lpv_history"] = self.width * self.height * 16
        return out
