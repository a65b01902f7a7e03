"""Lumen's first trace (lecture 21, "Speed of Different Tracing Methods"): every screen-probe ray
is first walked on the screen, through the HZB (at most 50 cells), and the mesh SDFs (to 1.8 m),
the global SDF and the sky go on from where the screen stops vouching for it (with the screen
colour's hits, only for the rays the screen does not resolve):

    hzb.depth_pyramid   this frame's HZB (MIN of window depths), once per frame
    screen_bounds       per pixel the neighbours' bound: the depth in front of which its column
                        is in front of its 4 neighbours' planes (glsl/screen_bounds.comp.glsl),
                        once per frame
    screen_trace_lib    per ray: where it hits what the camera sees, and how far it is known to
                        be empty (t_free: every cell it crossed, it crossed in front of what the
                        cell shows; at a pixel, at least a voxel in front of its surface and in
                        front of the neighbours' bound: the depth buffer shows neither what lies
                        within a voxel of a surface (a panel 5 cm under a ceiling, seen edge-on)
                        nor the sub-pixel rim of a neighbour's surface).
                        A ray that passes behind what a pixel shows without hitting it ends
                        there (SCREEN_BEHIND: what is behind is unknown; walking on found
                        surfaces past a thin wall's edge, `thin` leaked 1.98%)
    the hit's light     HITS "CACHE" (default): the walk only vouches for the empty part (it
                        ends at the first pixel that does not: free_only) and the SDF trace goes
                        on from t_free, a voxel back (unseen surfaces: a porch roof's underside),
                        in the same pass (screen_probe_lumen_trace): the mesh SDFs' last steps
                        find the hit and read the surface cache there, as without the screen.
                        Before (until the thirteenth session), a hit read the cache at the hit
                        pixel's plane lifted half a voxel, with no SDF steps: relMSE over the
                        SDF-only trace glow +2.0%, window +1.7%, textured +1.8% (the SDF's
                        half-voxel shell finds surfaces the screen's ray passes by; see the
                        README). "COLOUR" (the lecture's): the screen colour, this frame's direct
                        light and the last gather's indirect irradiance composited per pixel,
                        averaged over the ray's cone on the hit's surface (screen_cone); three
                        passes over compacted lists (screen_probe_screen_trace); a gather with no
                        history has none and traces on the SDFs alone. Measured (bench/quality.py,
                        128 px, 512 spp): COLOUR's relMSE is above the trace without the screen on
                        every scene (cornell 0.0104 / 0.0074, glow 0.0334 / 0.0209): the probes'
                        indirect light it carries is 5.8% below the cache's and noisier
    otherwise           (the ray leaves the screen, or passes behind what a pixel shows) the SDF
                        trace starts at t_free, not at the ray's origin
    a corner's rays     a ray that starts inside a surface's hit shell (a probe in a concave
                        corner) hits it at once, as on the SDFs alone: the walk leaves its start
                        pixel untested and vouched past the wall beside it (glow: half the rays
                        that differed from the SDF-only trace; test_screen_trace_corners). Tested
                        before the walk; any other ray's SDF trace starts at least where its
                        first step from the origin would land (that sample is this test's)

Why it is faster: the HZB walk costs a few texel fetches per cell, an SDF step evaluates every
object near the point; the screen finds the empty part of most of a room's rays. On llvmpipe the
gain is bounded: the SDF steps it can skip were 25-35% of the probe trace, the hit's
surface-cache read, which both pay, most of the rest. The walk once cost about what it saved:
its per-step test of the four neighbours' planes, compiled into the loop, slowed the trace by
5-16% even where no ray ran it (llvmpipe runs eight rays in step and pays for code by its size),
so that test is now a bound per pixel made once per frame (screen_bounds, ~20 ms at 640 x 360,
rebuilt only when the G-buffer is); a corner's ray skips the walk; and every other ray's SDF
trace starts at least where its first step from the origin would land (bench/f12_ab.py, the
README's issue 12 notes, twentieth session).
Why it is no less right: what it skips is what the depth buffer shows empty (the nearest
surfaces, a voxel's margin and the neighbours' rims kept, a voxel back for what the camera does
not see); what the screen does not show (behind, off screen) is still traced.
Objects hidden from the camera (visible_camera off: bench/quality.py's `thin` has its roof so)
are in the SDFs but not in the depth buffer, which therefore vouches for the space they fill:
before a screen result is used, the ray is sphere-traced against those objects alone (their
object-table rows in `screen_hidden`, SceneState.hidden_rows) up to where the screen result
ends, and where it comes within a voxel of one the SDF trace takes over from there (before this
guard `thin` leaked 37%).
Debug view TRACE_METHOD (gi_trace_method.comp.glsl): per pixel, the share of its rays served by
the screen (red: with CACHE hits, a hit on the surface of the pixel where the walk ended), the
mesh SDFs (green), the global SDF (blue), none (the sky: black).
Needs a GPU context.
"""
from __future__ import annotations

import numpy as np

from . import compute, hzb

# screen_camera: the frame's view_proj, its 4 columns in 4 RGBA32F texels (a sampler and not a
# push constant: the probe trace's push constants would pass Vulkan's 128 bytes)
# screen_hidden: R32F, the object-table rows of the camera-hidden instances (one texel of -1: none)
# screen_bounds: R32F, per pixel the neighbours' bound (BOUNDS)
SAMPLERS = ("gbuf_position", "gbuf_normal", "hzb", "screen_bounds", "screen_colour",
            "screen_camera", "screen_hidden")
# screen_cam: camera position xyz, w the thickness (m) a surface is assumed behind the depth
# buffer; screen_steps: HZB cells per ray (0: off)
PUSH = (('VEC4', 'screen_cam'), ('INT', 'screen_steps'))
# what a screen hit's light is: "CACHE" the surface cache's at the hit pixel's surface, half a
# voxel towards the ray (no SDF steps), "COLOUR" the screen colour (the lecture's; noisier and
# darker here: README)
HITS = ("CACHE", "COLOUR")
# 8 x 8 work groups: screen_bounds.comp.glsl's BOUNDS_TILE (a group shares its tile's planes)
BOUNDS = compute.Pass("screen_bounds", samplers=("gbuf_position", "gbuf_normal"),
                      images=(("bounds", 'R32F'),), push=(('MAT4', 'view_proj'),),
                      group=(8, 8, 1))
METHOD = compute.Pass("gi_trace_method", samplers=SAMPLERS,
                      push=PUSH + (('INT', 'rays'), ('INT', 'frame'), ('FLOAT', 't_max')))


def neighbour_bounds(gbuf: dict, view_proj, width: int, height: int):
    """Per pixel of this frame's G-buffer the neighbours' bound (R32F; BOUNDS,
    glsl/screen_bounds.comp.glsl): Lumen's walk vouches for a pixel's empty space only in front
    of it."""
    out = compute.texture((width, height), 'R32F')
    g = gbuf["textures"]
    BOUNDS.run((width, height), gbuf_position=g["position"], gbuf_normal=g["normal"],
               view_proj=view_proj, bounds=out)
    return out


class ScreenTrace:
    """This frame's HZB, neighbours' bounds and screen colour (held by the engine's SceneState
    between the iterations of one frame; rebuilt per frame)."""

    def __init__(self, gbuf: dict, view_proj, cam_pos, width: int, height: int, steps: int = 50,
                 thickness: float = 0.1, hidden=(), rays: int = 64, hit: str = "CACHE",
                 previous: "ScreenTrace | None" = None):
        self.gbuf, self.width, self.height = gbuf, int(width), int(height)
        self.view_proj = np.asarray(view_proj, np.float64)
        if hit not in HITS:
            raise ValueError(f"Screen Hit Light {hit!r}: use one of {HITS}")
        self.hit = hit
        self.camera = camera_texture(view_proj, ray_cone_tan(rays), self.hit == "CACHE")
        self.cam = compute.vec(cam_pos) + [float(thickness)]
        self.steps = int(steps)
        # the last redraw's HZB when the G-buffer is the very same (MeshBatches.draw reuses it
        # for the same view of the same instances): a still viewport builds it once, not every
        # redraw (7.6 ms of a 716 ms redraw at 640 x 360, bench/glsl_ab.py)
        same = (previous is not None and previous.gbuf["textures"]["position"]
                is gbuf["textures"]["position"])
        self.hzb = previous.hzb if same else hzb.depth_pyramid(gbuf, view_proj, width, height)
        self.bounds = previous.bounds if same else neighbour_bounds(gbuf, view_proj, width, height)
        self.hzb_reused = same
        self.colour = None
        self.hidden_count = len(hidden)
        self.hidden = hidden_texture(hidden)

    @property
    def needs_colour(self) -> bool:
        """Whether hits read the screen colour (`light` before each gather)."""
        return self.hit == "COLOUR"

    def light(self, direct_tex, e_history, sky):
        """The screen colour: the composite of this frame's direct light and the last gather's
        indirect irradiance (the probes' history: what the lecture calls last frame's scene
        colour, here on this frame's G-buffer, so nothing needs reprojecting)."""
        from . import composite

        inv_vp = np.linalg.inv(self.view_proj)
        self.colour = composite.composite(self.gbuf, direct_tex, e_history, sky, inv_vp,
                                          self.width, self.height)["textures"]["combined"]

    def inputs(self) -> dict:
        """A tracing pass's SAMPLERS and PUSH (compute.Pass keywords)."""
        g = self.gbuf["textures"]
        # the screen colour's hits: no gather yet to read, steps 0 (off)
        on = self.colour is not None or not self.needs_colour
        return dict(gbuf_position=g["position"], gbuf_normal=g["normal"], hzb=self.hzb,
                    screen_bounds=self.bounds,
                    screen_colour=(self.colour if self.colour is not None
                                   else compute.texture((1, 1))),
                    screen_camera=self.camera, screen_hidden=self.hidden,
                    screen_cam=self.cam, screen_steps=self.steps if on else 0)

    def method_image(self, resources, gsdf, cache, sky, voxels, t_max: float, rays: int = 8,
                     frame: int = 0) -> np.ndarray:
        """The TRACE_METHOD debug view (glsl/gi_trace_method.comp.glsl, read back: a debug view
        or a test asks for it): float32 [h, w, 4], per pixel the share of `rays` probe-like rays
        served by the screen (r), the mesh SDFs (g), the global SDF (b)."""
        out = compute.texture((self.width, self.height))
        METHOD.run((self.width, self.height), scene=resources, cache=cache, gsdf=gsdf, sky=sky,
                   voxels=voxels, **self.inputs(), rays=int(rays), frame=int(frame),
                   t_max=float(t_max), out_image=out)
        return compute.read(out)

    def stats(self) -> dict:
        """GPU bytes: HZB atlas and neighbours' bounds (R32F) and the screen colour (RGBA32F)."""
        out = {"screen_hzb": self.hzb.width * self.hzb.height * 4,
               "screen_bounds": self.bounds.width * self.bounds.height * 4}
        if self.colour is not None:
            out["screen_colour"] = self.colour.width * self.colour.height * 16
        return out


def camera_texture(view_proj, cone_tan: float = 0.0, hit_cache: bool = False):
    """view_proj as a 5x1 RGBA32F texture, texel k < 4 its column k (GLSL's mat4(c0, c1, c2,
    c3)), texel 4 x the tangent of the cone a ray stands for (its screen-colour footprint),
    y 1 where a hit's light is the surface cache's (HITS "CACHE")."""
    import gpu

    from .resources import float_buffer
    cols = np.zeros((5, 4), np.float32)
    cols[:4] = np.asarray(view_proj, np.float32).T     # row k = column k
    cols[4, 0] = cone_tan
    cols[4, 1] = 1.0 if hit_cache else 0.0
    return gpu.types.GPUTexture((5, 1), format='RGBA32F', data=float_buffer(cols.reshape(1, 5, 4)))


def ray_cone_tan(rays: int) -> float:
    """The tangent of the half-angle of a cone holding 1 / rays of the sphere (a probe's
    octahedral texel: rays = probe_res^2): 2 pi (1 - cos a) = 4 pi / rays."""
    c = 1.0 - 2.0 / max(float(rays), 2.0)
    return float(np.sqrt(max(1.0 - c * c, 0.0)) / max(c, 1e-6))


def hidden_texture(rows):
    """The camera-hidden instances' object-table rows as an R32F row texture (-1: none)."""
    import gpu

    from .resources import float_buffer
    r = np.asarray(rows, np.float32).reshape(-1)
    if not len(r):
        r = np.full(1, -1.0, np.float32)
    return gpu.types.GPUTexture((len(r), 1), format='R32F', data=float_buffer(r.reshape(1, -1)))
