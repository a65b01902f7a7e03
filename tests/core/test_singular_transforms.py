"""packing.singular_many: which world transforms the SDF scene cannot invert, for every instance
at once (SceneState.sync calls it each time objects move), against the per-matrix SVD test."""
import numpy as np

from gpu_shaders.packing import singular, singular_many


def _reference(mw) -> bool:
    mw = np.asarray(mw, np.float64)
    if not np.isfinite(mw).all():
        return True
    s = np.linalg.svd(mw[:3, :3], compute_uv=False)
    return bool(s.min() <= 1e-9 * max(s.max(), 1e-30))


def test_batched_singular_matches_one_at_a_time():
    rng = np.random.default_rng(3)
    m = rng.normal(size=(400, 4, 4))
    m[5, :3, :3] = 0.0                                   # scaled to 0
    m[7, 0, 0] = np.nan
    m[11, 1, 1] = np.inf
    m[13, :3, :3] = np.diag([1.0, 1.0, 1e-12])           # flattened
    m[20:30, :3, :3] *= 1e-20                            # tiny but well conditioned: fine
    m[31, :3, :3] = np.outer([1.0, 2.0, 3.0], [0.5, -1.0, 2.0])   # rank 1
    got = singular_many(m)
    np.testing.assert_array_equal(got, [_reference(x) for x in m])
    assert got[[5, 7, 11, 13, 31]].all() and not got[20:30].any()
    assert singular(m[5]) and not singular(np.eye(4)) and singular(np.eye(3))
    assert singular_many(np.zeros((0, 4, 4))).shape == (0,)
