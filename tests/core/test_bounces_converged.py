"""gi_settings.bounces_converged without Blender: an F12 render's warm-up stops when the light its
surface cache still misses, extrapolated from the last two bounces, is within the tolerance."""
import pytest

from gpu_shaders.gi_settings import GISettings, bounces_converged, from_scene


def series(r, k):
    """Totals after 0..k bounces of a geometric series with ratio r (first bounce 1)."""
    return [(1.0 - r ** i) / (1.0 - r) for i in range(k + 1)]


@pytest.mark.parametrize("r", [0.2, 0.5, 0.7, 0.85])
def test_stops_at_the_first_bounce_within_tolerance_of_the_limit(r):
    limit = 1.0 / (1.0 - r)
    stops = [k for k in range(2, 60) if bounces_converged(series(r, k), 0.02)]
    first = stops[0]
    # the estimate is exact on a geometric series: the first k with limit - e_k <= 2% of e_k
    exact = next(k for k in range(2, 60) if limit - series(r, k)[-1] <= 0.02 * series(r, k)[-1])
    assert first == max(exact, 2)
    assert stops == list(range(first, 60))          # and it stays converged


def test_a_room_needs_more_bounces_than_an_open_scene():
    room = next(k for k in range(2, 60) if bounces_converged(series(0.7, k), 0.02))
    ground = next(k for k in range(2, 60) if bounces_converged(series(0.1, k), 0.02))
    assert ground == 2 and room > 8


def test_edge_cases():
    assert not bounces_converged([0.0, 1.0], 0.02)          # one change: no ratio yet
    assert bounces_converged([0.0, 0.0, 0.0], 0.02)         # no light at all
    assert bounces_converged([0.0, 1.0, 1.0], 0.02)         # nothing changed
    assert not bounces_converged([0.0, 1.0, 1.2, 1.1], 0.02)  # oscillating by 10%: not yet
    assert not bounces_converged([0.0, 1e-9, 1.0], 0.02)    # ratio capped: 0.9 / 0.1 x 1


def test_scene_setting_reaches_the_settings():
    class Engine:
        converge_bounces = False
    assert GISettings().converge_bounces
    assert not from_scene(Engine()).converge_bounces
