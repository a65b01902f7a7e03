"""GISettings.render_sc_share without Blender: the share of surface-cache tiles an F12 iteration
relights spends at least the bounces - 1 full warm-ups' relights, lights every tile at least once,
and never exceeds every tile."""
from gpu_shaders.gi_settings import settings


def test_share_of_tiles_per_f12_iteration():
    assert settings().render_sc_share() == 0.2                          # default: 0.2 of the unseen tiles
    s = dict(render_sc_fraction=0.2)
    assert settings(**s).render_sc_share() == 0.2                       # 3 bounces, 8 frames: 2/10
    assert settings(bounces=8, render_frames=4, **s).render_sc_share() == 7 / 11
    assert settings(bounces=1, render_frames=8, **s).render_sc_share() == 0.2  # the floor
    assert settings(bounces=1, render_frames=2, **s).render_sc_share() == 0.5  # every tile once
    assert settings(bounces=1, render_frames=1, **s).render_sc_share() == 1.0
    for b in range(1, 12):
        for f in range(1, 12):
            s = settings(bounces=b, render_frames=f, render_sc_fraction=0.01)
            n = len(s.render_schedule())
            assert 1.0 / n <= s.render_sc_share() <= 1.0
            assert s.render_sc_share() * n >= b - 1 - 1e-9
