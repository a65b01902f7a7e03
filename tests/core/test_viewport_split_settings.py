"""The viewport's split in the settings (gi_settings.from_scene): the viewport spreads a
refinement step over VIEWPORT_SPLIT redraws (a quarter of the preset's surface-cache tiles; the
probes keep their octahedral resolution, tracing a quarter of it per redraw); F12 is untouched, and a user's own
Cache Texels per Frame is a per-redraw budget, kept as it is."""
from types import SimpleNamespace

import pytest

from gpu_shaders import gi_settings


def scene(**kw):
    base = dict(render_quality="MEDIUM", viewport_quality="MEDIUM", cache_texels_per_frame=0)
    return SimpleNamespace(**dict(base, **kw))


def test_viewport_splits_and_f12_does_not():
    f12 = gi_settings.from_scene(scene())
    vp = gi_settings.from_scene(scene(), viewport=True)
    assert f12.split == 1 and vp.split == gi_settings.VIEWPORT_SPLIT == 4
    assert f12.probe_res_for(640, 360) == vp.probe_res_for(640, 360) == 8
    assert vp.split_step == 2 and f12.split_step == 1
    preset = gi_settings.PRESETS["MEDIUM"]
    assert f12.sc_tiles == preset["sc_tiles"] and vp.sc_tiles == preset["sc_tiles"] // 4


def test_user_cache_budget_is_per_redraw():
    vp = gi_settings.from_scene(scene(cache_texels_per_frame=5000), viewport=True)
    assert vp.sc_tiles == 5


def test_bad_split_raises():
    with pytest.raises(ValueError, match="split 3"):
        gi_settings.settings("LOW", split=3).split_step


def test_pixel_size_counts_the_region_shown():
    """Pixel Size 2 at a 640x360 region: a 320x180 image keeps the preset's 16 px tile (a
    quarter of the probes), where a 320x180 F12 image halves it (MIN_PROBES_ACROSS)."""
    vp = gi_settings.from_scene(scene(), viewport=True)
    assert vp.probe_tile_for(320, 180) == 8
    from dataclasses import replace
    assert replace(vp, pixel_size=2).probe_tile_for(320, 180) == 16
    assert replace(vp, pixel_size=2).probe_tile_for(64, 64) == 8
