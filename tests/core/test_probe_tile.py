"""GISettings.probe_tile_for without Blender: a small image gets at least MIN_PROBES_ACROSS screen
probes across its shorter side (the tile halved, not below 8 px); from 16 x the preset's tile up
the preset's tile is kept."""
from gpu_shaders import gi_settings
from gpu_shaders.gi_settings import settings


def test_probe_tile_by_image_size():
    assert gi_settings.MIN_PROBES_ACROSS == 16
    medium = settings("MEDIUM")
    assert medium.probe_tile == 16
    assert medium.probe_tile_for(128, 128) == 8          # the benchmark's size: 16 probes across
    assert medium.probe_tile_for(255, 1000) == 8         # the shorter side decides
    assert medium.probe_tile_for(256, 256) == 16
    assert medium.probe_tile_for(1920, 1080) == 16
    assert medium.probe_tile_for(32, 32) == 8            # never below 8 px
    assert settings("HIGH").probe_tile_for(128, 128) == 8
    assert settings("LOW").probe_tile_for(200, 300) == 8
    for w in range(8, 600, 7):
        t = medium.probe_tile_for(w, w)
        assert t in (8, 16)
        assert t == 8 or w // t >= gi_settings.MIN_PROBES_ACROSS


def test_probe_res_follows_the_tile(monkeypatch):
    """A halved tile scales the probes' octahedral resolution with it (the preset's rays per
    pixel), not below MIN_PROBE_RES (default 8: measured, fewer rays lose quality); the
    preset's tile keeps the preset's resolution."""
    assert gi_settings.MIN_PROBE_RES == 8
    medium = settings("MEDIUM")
    for floor, small in ((8, 8), (6, 6), (4, 4), (2, 4)):
        monkeypatch.setattr(gi_settings, "MIN_PROBE_RES", floor)
        assert medium.probe_res_for(128, 128) == small      # 4: 16 rays x 4 probes = 64
        assert medium.probe_res_for(1920, 1080) == medium.probe_res == 8
        assert medium.probe_res_for(256, 256) == 8
        assert settings("HIGH").probe_res_for(128, 128) == 8     # High's tile is not halved
        for w in range(8, 600, 7):
            r, t = medium.probe_res_for(w, w), medium.probe_tile_for(w, w)
            assert r == (8 if t == 16 else small)
