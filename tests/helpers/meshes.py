"""Small analytic meshes for tests: icosphere, torus, box (numpy only)."""
import numpy as np


def icosphere(subdivisions=3, radius=1.0):
    t = (1 + 5 ** 0.5) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t],
                  [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
                  [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
                  [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    for _ in range(subdivisions):
        edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        uniq, inv = np.unique(edges, axis=0, return_inverse=True)
        mids = v[uniq].mean(axis=1)
        mids /= np.linalg.norm(mids, axis=1, keepdims=True)
        m = inv.reshape(3, -1).T + len(v)
        a, b, c = f.T
        ab, bc, ca = m.T
        f = np.concatenate([np.c_[a, ab, ca], np.c_[b, bc, ab], np.c_[c, ca, bc], np.c_[ab, bc, ca]])
        v = np.vstack([v, mids])
    return v * radius, f.astype(np.int32)


def torus(R=3.0, r=1.0, nu=48, nv=24):
    u, w = np.meshgrid(np.arange(nu) * 2 * np.pi / nu, np.arange(nv) * 2 * np.pi / nv, indexing="ij")
    x = (R + r * np.cos(w)) * np.cos(u)
    y = (R + r * np.cos(w)) * np.sin(u)
    z = r * np.sin(w)
    v = np.stack([x, y, z], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a = i * nv + j
    b = ((i + 1) % nu) * nv + j
    c = ((i + 1) % nu) * nv + (j + 1) % nv
    d = i * nv + (j + 1) % nv
    f = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return v, f.astype(np.int32)


def box(lo, hi, n=4):
    """Closed outward box [lo, hi] (mm), each side an n x n grid of quads split in two."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    verts, faces = [], []
    s = np.linspace(0, 1, n + 1)
    for axis in range(3):
        for side in (0, 1):
            a, b = [x for x in range(3) if x != axis]
            uu, vv = np.meshgrid(s, s, indexing="ij")
            p = np.zeros(uu.shape + (3,))
            p[..., axis] = hi[axis] if side else lo[axis]
            p[..., a] = lo[a] + uu * (hi[a] - lo[a])
            p[..., b] = lo[b] + vv * (hi[b] - lo[b])
            base = sum(len(x) for x in verts)
            verts.append(p.reshape(-1, 3))
            i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
            q0, q1 = i * (n + 1) + j, (i + 1) * (n + 1) + j
            faces.append(np.concatenate([np.stack([q0, q1, q1 + 1], -1).reshape(-1, 3),
                                         np.stack([q0, q1 + 1, q0 + 1], -1).reshape(-1, 3)]) + base)
    v, f = np.concatenate(verts), np.concatenate(faces)
    c = v[f].mean(1)
    nrm = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    flip = np.einsum("ij,ij->i", nrm, c - 0.5 * (lo + hi)) < 0
    f[flip] = f[flip][:, ::-1]
    u, inv = np.unique(np.round(v, 9), axis=0, return_inverse=True)
    return u, inv.ravel()[f].astype(np.int32)


def tiled_spheres(copies=13, subdivisions=6, radius=10.0):
    """``copies`` icospheres side by side (13 x 81,920 = 1,064,960 triangles by default): a
    million-triangle mesh with a known size, for file-size tests and write benchmarks."""
    v, f = icosphere(subdivisions, radius)
    k = np.arange(copies)
    vv = (v[None] + np.c_[k * 25.0, k * -3.5, k * 0.125][:, None]).reshape(-1, 3)
    ff = (f[None] + (k * len(v))[:, None, None]).reshape(-1, 3)
    return vv, ff.astype(np.int32)
