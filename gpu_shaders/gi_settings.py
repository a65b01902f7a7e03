"""Global illumination settings of the preview engine: quality presets and the scene's controls
(no bpy, no gpu: `from_scene` reads plain attributes, so scripts and tests can pass any object).

The scene's engine settings (`scene.lumen.engine`, operators/properties.py) take their defaults
from `GISettings()` and CACHE_TEXELS_PER_FRAME here, so each default is stated once.
A preset sets the per-frame budgets; the scene's `bounces` and `render_frames` say how much an
F12 render accumulates:
    probe_tile       pixels per screen probe side (lecture: 16; probe_tile_for: halved on a small image)
    probe_res        octahedral texels per probe side (lecture: 8 -> 64 rays per probe;
                     probe_res_for: kept on a small image, see MIN_PROBE_RES)
    gsdf_n, gsdf_voxel  global SDF clipmap texels per side and level-0 voxel (metres)
    history          viewport temporal filter: exponential over about this many frames
    sc_tiles         viewport surface-cache budget: tiles of 32x32 lighting texels relit per
                     refinement step, so per redraw / split (surface_cache_pages.py; F12: the
                     tiles the view reads and render_sc_share() of the others per iteration,
                     by priority); the scene's Cache Texels per Frame overrides it (per redraw)
`split` (the viewport: VIEWPORT_SPLIT; F12: 1): one refinement step of the viewport is spread over
`split` redraws, as EEVEE's viewport takes one sample per redraw: each redraw integrates one pixel
of every sqrt(split)^2 block (screen_probes.ScreenProbes.temporal_split fills and blends the rest),
its probes, placed anew every split redraws, trace one texel of every sqrt(split)^2 block of
their octahedral map per redraw (the others keep earlier redraws' rays: a pixel's turn comes
every split redraws, when every texel has been traced again, so each of its samples has the
noise of a whole probe), the surface cache relights sc_tiles / split tiles, and the history holds
`history` samples per pixel, so `history` x split redraws. Why: a still 640x360 redraw was 2.4x EEVEE's one-sample frame
(bench/pass_profile.py: probe rays 51%, per-pixel integration 19%).
`voxel_lighting` (on unless a settings object says otherwise): a global-SDF hit is searched among
its voxel tile's objects and reads the voxel lighting (voxel_lighting.py); off, it is searched on
every mesh SDF and reads the surface cache, whose cost grows with the number of objects.
`radiance_cache` (off unless a settings object says otherwise: the scene's `radiance_cache`):
screen-probe rays trace ~2 m and take the far field from the world radiance cache
(radiance_cache.py; rc_spacing, rc_budget probes traced per viewport frame, new first, of
them at most rc_retrace re-traced, rc_capacity slots); an F12 render traces every probe it
needs on every gathered frame.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

PRESETS = {
    "LOW": dict(probe_tile=16, probe_res=8, gsdf_n=32, gsdf_voxel=0.2, history=8, sc_tiles=16),
    "MEDIUM": dict(probe_tile=16, probe_res=8, gsdf_n=48, gsdf_voxel=0.125, history=12, sc_tiles=32),
    "HIGH": dict(probe_tile=8, probe_res=8, gsdf_n=64, gsdf_voxel=0.1, history=16, sc_tiles=64),
}
QUALITIES = ("OFF",) + tuple(PRESETS)
CACHE_TEXELS_PER_FRAME = 0         # viewport surface-cache texels per frame (0: the preset's)
MIN_PROBES_ACROSS = 16             # screen probes across an image's shorter side, at least
MIN_PROBE_RES = 8                  # octahedral texels per side a halved-tile probe keeps, at least
MIN_RENDER_FRAMES = 4              # F12 frames averaged before the noise threshold may end it
MAX_BOUNCES = 16                   # F12 bounces at most (the scene's Bounces setting's maximum)
SEED_FRAMES = 4096                 # F12: GI frames between two seeds' jitter sequences (more than
                                   # any render's iterations)
RENDER_SC_MIN_TILES = 256          # F12's tile cap (render_sc_texels) never goes below this
VIEWPORT_SPLIT = 4                 # the viewport's GISettings.split by default (1, 4 or 16;
                                   # the scene's viewport_split, Viewport > Spread over)


@dataclass(frozen=True)
class GISettings:
    quality: str = "MEDIUM"        # OFF: direct light and SDF sky occlusion only
    bounces: int = 3               # surface-cache bounces an F12 render converges before gathering
                                   # (with converge_bounces: at least; bounces_converged)
    converge_bounces: bool = True  # F12: more bounces (up to MAX_BOUNCES) until the cache's light
    bounce_tolerance: float = 0.02  # is estimated within this share of where it converges
    render_frames: int = 8         # F12: frames of jittered probes averaged (temporal accumulation;
                                   # with noise_threshold > 0: at most)
    noise_threshold: float = 0.01  # F12: stop averaging frames (after MIN_RENDER_FRAMES) once the
                                   # mean's relative noise is below this (frame_noise.py; 0: off;
                                   # Cycles' adaptive sampling default)
    aa_samples: int = 32           # F12: jittered G-buffers averaged (antialias.py; 1: off)
    seed: int = 0                  # F12: which jitter sequences its GI frames take (Cycles' Seed:
                                   # renders differ only in noise; bench/quality.py's noise level)
    probe_tile: int = 16
    probe_res: int = 8
    gsdf_n: int = 48
    gsdf_voxel: float = 0.125
    history: int = 12
    sc_tiles: int = 32
    gather: str = "PROBES"         # PROBES (screen probes) or PIXEL (reference: rays per pixel)
    pixel_rays: int = 64           # PIXEL: cosine rays per pixel per frame
    voxel_lighting: bool = True    # far (global-SDF) hits read voxel lighting
    cache_relax: float = 1.5       # F12: the surface cache's over-relaxation (1: plain bounces)
    render_sc_fraction: float = 0.2    # F12: least share of the tiles the view does not read
                                       # (surface_cache_pages.seen) relit per iteration, by
                                       # priority (render_sc_share; UE: 0.125); 1: every tile
    render_sc_texels: float = 16.0     # F12: at most this many lighting texels relit per image
                                       # pixel per iteration once every tile is lit (0: no cap)
    sc_lod_rays: float = 1.0       # surface-cache ray LOD: a probe traces 16, 8 or 4 rays,
                                   # at least this many per pixel its 4x4 texels cover (0: 16)
    radiance_cache: bool = False   # screen-probe rays trace ~2 m, the far field from the cache
    # screen-probe rays importance-sampled (BRDF x last radiance). Off by default: on, quality.py
    # 128 px relMSE glow 0.0801 -> 0.0861 (gpu_shaders/README: Screen probes)
    probe_importance: bool = False
    adaptive_probes: bool = True   # probes at 8x8 / 4x4 tiles where interpolation fails
    rc_spacing: float = 0.577      # radiance cache level-0 probe spacing (m): 2 m screen rays
    rc_budget: int = 16            # radiance cache probes traced per viewport frame (new first)
    rc_retrace: int = 8            # of them, at most this many re-traced (least recent first)
    rc_capacity: int = 2048        # radiance cache probe slots
    screen_trace: bool = False     # probe rays walk the HZB first (Lumen's first trace); off:
                                   # relMSE +3.9% on glow and +2.6% on textured against the
                                   # SDF-only trace, probe rays no faster on cornell (README)
    screen_hit: str = "CACHE"      # a screen hit's light: the surface cache's ("CACHE") or the
                                   # screen colour ("COLOUR", the lecture's): screen_trace.HITS
    screen_steps: int = 50         # HZB cells per screen ray (the lecture's "HZB Max Step=50")
    screen_thickness: float = 0.1  # metres a surface is assumed thick behind the depth buffer
    pixel_size: int = 1            # the viewport's Pixel Size (engine.frame): probe_tile_for
                                   # counts probes across the region shown, not the image
    split: int = 1                 # redraws one refinement step is spread over (from_scene:
                                   # VIEWPORT_SPLIT in the viewport, 1 for F12; see `split`)

    @property
    def enabled(self) -> bool:
        return self.quality != "OFF"

    @property
    def cache_blend(self) -> float:
        """The surface cache's blend per bounce update: cache_relax, at least 1 (F12's every
        iteration, the viewport's tiles until their `history` count)."""
        return max(float(self.cache_relax), 1.0)

    def render_schedule(self):
        """F12: [(surface-cache blend or None, probe blend or None), ...] per iteration. The first
        bounces - 1 iterations replace the cache's indirect light (one more bounce each) and
        gather nothing; then render_frames iterations gather into a running mean while the cache
        goes on replacing (one more bounce each, as in the viewport): each frame's gather reads
        a fresh estimate of the cache, so its noise is averaged by the gather's mean.
        Measured (bench/quality.py, 128x128, against averaging the cache over the frames as
        well, which weighted its early, short-bounce states like its last): relMSE window
        0.0575 -> 0.0417 (bias -22.0% -> -15.5%), glow 0.134 -> 0.097 (-25.6% -> -22.4%),
        cornell 0.0366 -> 0.0367 (-6.2% -> -4.3%), at the same cost. (Re-tracing the cache only
        every other frame was measured too: 2x faster cache, but the window room's relMSE rose
        from 0.060 to 0.067: its light needs every bounce.)
        The cache's blend is `cache_relax` (> 1: over-relaxation, applied per texel only where
        the update goes the way its last one went; surface_cache_indirect.comp.glsl)."""
        w = self.cache_blend
        warm = [(w, None)] * max(self.bounces - 1, 0)
        frames = max(self.render_frames, 1)
        return warm + [(w, 1.0 / (j + 1)) for j in range(frames)]

    def probe_tile_for(self, width: int, height: int) -> int:
        """The screen-probe tile for a width x height image: the preset's, halved (not below 8
        px) while the shorter side has fewer than MIN_PROBES_ACROSS probes. Why: the probes
        sample the irradiance field, and a 16 px tile leaves a small image 8 probes across;
        a Cornell box's ceiling (18 rows at 128 px) then got one row of probes, its front-to-
        back gradient flattened (1.66x the reference's irradiance at the front, 0.72x at the
        back). bench/quality.py cornell at 128 px, 512 spp, tile 16 -> 8: relMSE 0.0179 ->
        0.0081, SSIM 0.930 -> 0.950. From 256 px up (16 x 16) nothing changes. The viewport
        counts the region it shows (the image x pixel_size): a Pixel Size of 2 renders a quarter
        of the pixels and, with the preset's tile, a quarter of the probes, as Cycles and EEVEE
        do a quarter of their work (halving the tile there kept every probe ray: Pixel Size 2
        was 1.70x EEVEE's frame where Pixel Size 1 was 2.13x)."""
        t = max(int(self.probe_tile), 1)
        short = min(int(width), int(height)) * max(int(self.pixel_size), 1)
        while t > 8 and short < MIN_PROBES_ACROSS * t:
            t //= 2
        return t

    def probe_res_for(self, width: int, height: int) -> int:
        """The probes' octahedral resolution for a width x height image: the preset's, scaled
        with the tile probe_tile_for picks (the same rays per pixel as the preset's tile), not
        below MIN_PROBE_RES. Why: the denser probes of a small image each trace probe_res^2
        rays, so halving the tile alone costs 4x the probe rays. MIN_PROBE_RES is 8 (no cut)
        because every cut measured lost quality (bench/quality.py 128 px, lumen_res4/6/8):
        glow relMSE 0.0537 / 0.0326 / 0.0252 at res 4 / 6 / 8, cornell 0.0100 / 0.0090 /
        0.0081 (SSIM 0.928 / 0.941 / 0.950), for 0.44x / 0.80x of cornell's F12 time."""
        r = max(int(self.probe_res), 1)
        t = self.probe_tile_for(width, height)
        if t < self.probe_tile:
            r = min(r, max(MIN_PROBE_RES, r * t // max(int(self.probe_tile), 1)))
        return r

    @property
    def split_step(self) -> int:
        """sqrt(split): the side of the pixel blocks the viewport integrates one pixel of per
        redraw, and of the probe texel blocks it traces one texel of."""
        step = {1: 1, 4: 2, 16: 4}.get(int(self.split))
        if step is None:
            raise ValueError(f"GI split {self.split!r}: use 1, 4 or 16")
        return step

    def render_sc_share(self) -> float:
        """F12: the share of the surface-cache tiles the view does not read that each iteration
        relights (the lecture's update budget). Every iteration relights every never-lit tile
        and every tile the view reads (PageSchedule.seen: a visible tile's rays reach it);
        PageSchedule.render_priority picks this share of the others: age x (visible: 4) /
        (1 + distance / 10 m), from each tile's own world box. At least render_sc_fraction,
        (bounces - 1) / iterations and 1 / iterations; 1 relights every tile every iteration.
        Measured before `seen` (a share of every tile, then of the tiles not facing the
        camera) (bench/quality.py scenes, 128 px; CPU seconds of the F12 call in one process,
        the machine loaded): with 0.2, thin 86.3 -> 23.4 s at relMSE 0.0221 -> 0.0220, yard
        27.9 s (EEVEE 64 spp: 42.7 s) at 0.0137 -> 0.0135; but the rooms lit by bounces lose
        light: window relMSE 0.0369 -> 0.0931 (bias -11.7% -> -30.5%), glow 0.0802 -> 0.1917,
        imported 0.0176 -> 0.0319, cornell 0.0374 -> 0.0367 (bias -3.3% -> -9.0%): the rooms
        need every wall relit every iteration, which `seen` now does (bench/quality_scenes
        tiles relit per iteration with 0.2: cornell 33 of 36, window 88/104, glow 32/32,
        imported 61/63, textured 51/64, thin 113/170, yard 124/221)."""
        n = len(self.render_schedule())
        return min(max(float(self.render_sc_fraction), (self.bounces - 1) / n, 1.0 / n), 1.0)


def bounces_converged(totals, tolerance: float) -> bool:
    """Whether an F12 render's surface cache has taken enough bounces: `totals` is its total
    indirect light after each warm-up iteration, from the reset (0) on. Each bounce adds about r
    times the last one's change (r: the ratio of the last two changes, at most 0.9), so the light
    still missing is about |last change| r / (1 - r); converged when that is within `tolerance`
    of the total. Why: a fixed count stops a room lit through a window short (bench/quality.py
    window: bounces 12 is 5% brighter than 3) and spends bounces an open scene does not need."""
    e = [float(x) for x in totals]
    if len(e) < 3:
        return False
    d1, d2 = abs(e[-2] - e[-3]), abs(e[-1] - e[-2])
    if e[-1] <= 0.0 or d2 == 0.0:
        return True
    r = min(d2 / d1, 0.9) if d1 > 0.0 else 0.9
    return d2 * r / (1.0 - r) <= tolerance * abs(e[-1])


def settings(quality: str = "MEDIUM", **overrides) -> GISettings:
    if quality not in QUALITIES:
        raise ValueError(f"GI quality {quality!r}: use one of {QUALITIES}")
    base = PRESETS.get(quality, PRESETS["LOW"])
    return replace(GISettings(quality=quality, **base), **overrides)


def from_scene(engine_settings, viewport: bool = False) -> GISettings:
    """GISettings from a scene's engine settings (`scene.lumen.engine`, or anything with those
    attributes): the render quality for F12, the viewport quality for the viewport."""
    d = GISettings()
    s = engine_settings
    q = getattr(s, "render_quality", d.quality)
    extra = {}
    if viewport:
        q = getattr(s, "viewport_quality", q)
        extra["split"] = int(getattr(s, "viewport_split", VIEWPORT_SPLIT))
    texels = int(getattr(s, "cache_texels_per_frame", CACHE_TEXELS_PER_FRAME) or 0)
    if texels > 0:
        extra["sc_tiles"] = -(-texels // 1024)
    out = settings(q, bounces=int(getattr(s, "bounces", d.bounces)),
                    render_frames=int(getattr(s, "render_frames", d.render_frames)),
                    aa_samples=int(getattr(s, "aa_samples", d.aa_samples)),
                    gather=str(getattr(s, "gi_gather", d.gather)),
                    voxel_lighting=bool(getattr(s, "voxel_lighting", d.voxel_lighting)),
                    radiance_cache=bool(getattr(s, "radiance_cache", d.radiance_cache)),
                    screen_trace=bool(getattr(s, "screen_trace", d.screen_trace)),
                    screen_hit=str(getattr(s, "screen_hit", d.screen_hit)),
                    adaptive_probes=bool(getattr(s, "adaptive_probes", d.adaptive_probes)),
                    probe_importance=bool(getattr(s, "probe_importance", d.probe_importance)),
                    converge_bounces=bool(getattr(s, "converge_bounces", d.converge_bounces)),
                    noise_threshold=float(getattr(s, "noise_threshold", d.noise_threshold)),
                    seed=int(getattr(s, "seed", d.seed)),
                    **extra)
    if out.split > 1 and "sc_tiles" not in extra:   # the preset's budget, spread as the rest
        out = replace(out, sc_tiles=max(out.sc_tiles // out.split, 1))
    return out
