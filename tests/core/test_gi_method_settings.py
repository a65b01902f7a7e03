"""gpu_shaders.gi_methods.from_scene without Blender: VXGI is built, its settings are read with
defaults (the scene properties may not exist yet) and clamped, and its cones read the sky (the
direct pass leaves it to them, as with Lumen)."""
from types import SimpleNamespace

from gpu_shaders import gi_methods


def test_vxgi_settings_defaults_clamps_and_sky():
    s, notes = gi_methods.from_scene(SimpleNamespace(gi_method="VXGI"))
    assert s.method == "VXGI" and notes == []
    assert (s.vxgi_cones, s.vxgi_cone_angle, s.vxgi_distance, s.vxgi_step, s.vxgi_offset) == \
        (6, 60.0, 20.0, 1.0, 1.0)
    s, _ = gi_methods.from_scene(SimpleNamespace(gi_method="VXGI", vxgi_cones=0,
                                                 vxgi_cone_angle=500.0, vxgi_step=0.0))
    assert (s.vxgi_cones, s.vxgi_cone_angle, s.vxgi_step) == (1, 180.0, 0.1)
    assert not gi_methods.direct_has_sky(s, gi_enabled=True)
    assert gi_methods.direct_has_sky(s, gi_enabled=False)
    ssgi, _ = gi_methods.from_scene(SimpleNamespace(gi_method="SSGI"))
    assert gi_methods.direct_has_sky(ssgi, gi_enabled=True)
    lpv, notes = gi_methods.from_scene(SimpleNamespace(gi_method="LPV"))
    assert lpv.method == "LPV" and notes == []
    unknown, notes = gi_methods.from_scene(SimpleNamespace(gi_method="PATH_TRACE"))
    assert unknown.method == "LUMEN" and "not built yet" in notes[0]
