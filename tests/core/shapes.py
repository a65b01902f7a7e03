"""Test meshes built in code, each with its exact answer where one exists."""
from pathlib import Path

import numpy as np

SHARED_MESHES = Path(__file__).resolve().parents[2].parent / "shared" / "meshes"


def shared_mesh_names():
    """Names of the shared test meshes beside the checkout (empty when they are absent)."""
    return sorted(p.stem for p in SHARED_MESHES.glob("*.obj")) if SHARED_MESHES.is_dir() else []


def grid_surface(f, nu, nv, wrap_u=True, wrap_v=True):
    """Triangulate a parametric surface f(u, v) in [0,1)^2 -> (N, 3) points."""
    u = np.arange(nu) / nu if wrap_u else np.linspace(0, 1, nu)
    v = np.arange(nv) / nv if wrap_v else np.linspace(0, 1, nv)
    U, V = np.meshgrid(u, v, indexing="ij")
    pts = f(U.ravel(), V.ravel())
    i, j = np.meshgrid(np.arange(nu if wrap_u else nu - 1), np.arange(nv if wrap_v else nv - 1), indexing="ij")
    i, j = i.ravel(), j.ravel()
    a = i * nv + j
    b = ((i + 1) % nu) * nv + j
    c = ((i + 1) % nu) * nv + (j + 1) % nv
    d = i * nv + (j + 1) % nv
    return pts, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def icosphere(radius=0.5, subdivisions=4):
    t = (1 + 5 ** 0.5) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
                  [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
                  [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    for _ in range(subdivisions):
        e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        uniq, inv = np.unique(e, axis=0, return_inverse=True)
        mid = len(v) + inv.reshape(3, -1).T          # midpoints of edges 01, 12, 20
        v = np.concatenate([v, (v[uniq[:, 0]] + v[uniq[:, 1]]) / 2])
        a, b, c = f.T
        ab, bc, ca = mid.T
        f = np.concatenate([np.stack(x, 1) for x in ([a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca])])
    v = v / np.linalg.norm(v, axis=1, keepdims=True) * radius
    return v, f


def box(half=(0.5, 0.4, 0.3)):
    """Closed box, outward faces; exact SDF in box_sdf."""
    hx, hy, hz = half
    v = np.array([[x, y, z] for x in (-hx, hx) for y in (-hy, hy) for z in (-hz, hz)], float)
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return v, f


def box_sdf(p, half):
    q = np.abs(p) - np.asarray(half)
    return np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0)


def torus(R=0.6, r=0.2, nu=96, nv=48):
    def f(u, v):
        a, b = 2 * np.pi * u, 2 * np.pi * v
        return np.stack([(R + r * np.cos(b)) * np.cos(a), (R + r * np.cos(b)) * np.sin(a), r * np.sin(b)], 1)
    return grid_surface(f, nu, nv)


def open_cylinder(radius=0.3, height=1.6, nu=96, nv=24):
    """A tube without caps: an open mesh with two boundary loops."""
    def f(u, v):
        a = 2 * np.pi * u
        return np.stack([radius * np.cos(a), radius * np.sin(a), (v - 0.5) * height], 1)
    return grid_surface(f, nu, nv, wrap_v=False)


def thin_wall(size=1.0, thickness=0.01):
    """A closed slab 1 cm thick: thinner than a voxel at ordinary densities."""
    return box((size / 2, size / 2, thickness / 2))


def surface_samples(v, f, n, rng):
    """Area-weighted random points on the triangles."""
    tri = v[f]
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    idx = rng.choice(len(f), n, p=area / area.sum())
    r1, r2 = np.sqrt(rng.random(n)), rng.random(n)
    t = tri[idx]
    return t[:, 0] * (1 - r1)[:, None] + t[:, 1] * (r1 * (1 - r2))[:, None] + t[:, 2] * (r1 * r2)[:, None]


def room_with_pillar(half=(3.0, 2.0, 1.5), pillar=(0.3, 0.3, 1.49)):
    """One mesh: a closed room whose walls face inwards (seen from inside) and a pillar in it
    from 1 cm above the floor to 1 cm under the ceiling, facing outwards. The six bounds cards
    see none of it from outside. Not flush: a pillar end in the floor's plane is a face
    coincident with the floor's, invisible, and which of the two a card's ray reports is
    Embree's tie to break, differently on different CPUs (coverage 0.988 on an AMD EPYC without
    AVX-512; 0.9987 with the 1 cm gap)."""
    rv, rf = box(half)
    rf = rf[:, ::-1]                       # flip: normals point into the room
    pv, pf = box(pillar)
    pv = pv + np.array([0.8, 0.4, 0.0])
    return np.concatenate([rv, pv]), np.concatenate([rf, pf + len(rv)])


def matrix(loc, rz=0.0, scale=1.0):
    """4x4 world matrix: uniform scale, then a rotation about Z by rz radians, then a translation."""
    m = np.eye(4)
    c, s = np.cos(rz), np.sin(rz)
    m[:3, :3] = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) * scale
    m[:3, 3] = loc
    return m
