"""Analytic shapes for the print checks and tools: a lens with sharp rims (two spherical caps),
and bodies with thin sheets and rods as isosurfaces of signed distance functions."""
import numpy as np


def lens(rim_radius=10.0, half_angle_deg=40.0, rings=30, segments=120):
    """Two spherical caps meeting at a sharp rim of radius ``rim_radius`` in z = 0, each surface
    meeting the rim plane at ``half_angle_deg`` (the wedge's half-angle at the rim). Closed,
    outward, exact vertices on the spheres."""
    a = np.radians(half_angle_deg)
    big = rim_radius / np.sin(a)
    h = big - big * np.cos(a)
    phi = np.arange(segments) * 2 * np.pi / segments

    def circle(theta, sign):
        r = big * np.sin(theta)
        z = sign * (big * np.cos(theta) - big * np.cos(a))
        return np.stack([r * np.cos(phi), r * np.sin(phi), np.full_like(phi, z)], 1)

    thetas = a * (1 - np.arange(1, rings) / rings)
    v = np.concatenate([circle(a, 1)] + [circle(th, s) for s in (1, -1) for th in thetas]
                       + [np.array([[0, 0, h], [0, 0, -h]])])
    n, j = segments, np.arange(segments)
    j1 = (j + 1) % n
    faces = []
    for rows, pole, s in (([0] + list(range(1, rings)), len(v) - 2, 1),
                          ([0] + list(range(rings, 2 * rings - 1)), len(v) - 1, -1)):
        for r0, r1 in zip(rows[:-1], rows[1:]):
            q = [r0 * n + j, r0 * n + j1, r1 * n + j1, r1 * n + j]
            f = np.concatenate([np.stack([q[0], q[1], q[2]], 1), np.stack([q[0], q[2], q[3]], 1)])
            faces.append(f if s > 0 else f[:, ::-1])
        f = np.stack([rows[-1] * n + j, rows[-1] * n + j1, np.full(n, pole)], 1)
        faces.append(f if s > 0 else f[:, ::-1])
    f = np.concatenate(faces)
    return v, f.astype(np.int32)


def box_sdf(p, lo, hi):
    c, h = (np.asarray(lo, float) + hi) / 2, (np.asarray(hi, float) - lo) / 2
    q = np.abs(p - c) - h
    return np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(1), 0)


def capsule_sdf(p, a, b, r):
    a, b = np.asarray(a, float), np.asarray(b, float)
    ab = b - a
    t = np.clip(((p - a) @ ab) / (ab @ ab), 0, 1)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1) - r


def sdf_mesh(sdf, lo, hi, step):
    """The zero level of ``sdf`` (negative inside) on a grid of ``step`` mm over [lo, hi]."""
    from anatomesh.core.extract.isosurface import isosurface

    axes = [np.arange(a, b + step / 2, step) for a, b in zip(lo, hi)]
    x = np.stack(np.meshgrid(*axes, indexing="ij"), -1)
    d = sdf(x.reshape(-1, 3)).reshape(x.shape[:3])
    aff = np.eye(4)
    aff[:3, :3] *= step
    aff[:3, 3] = lo
    m = isosurface((-d).astype(np.float32), 0.0, affine=aff)
    return m.vertices.astype(np.float64), m.faces


def body_with_fin_and_rod(sheet=0.5, rod=0.6, step=0.125):
    """A 10 x 10 x 6 mm block; on top a fin ``sheet`` mm thick (x) standing from z = 6 to 14 over
    y = 1..9 (one side 8 x 8 = 64 mm², centred at (5, 5, 10)); from its +x side a rod of
    diameter ``rod`` along +x to x = 22 (12 mm beyond the block, centred at (16, 5, 3))."""
    def sdf(p):
        block = box_sdf(p, (0, 0, 0), (10, 10, 6))
        fin = box_sdf(p, (5 - sheet / 2, 1, 5.5), (5 + sheet / 2, 9, 14))
        stick = capsule_sdf(p, (9, 5, 3), (22, 5, 3), rod / 2)
        return np.minimum(np.minimum(block, fin), stick)
    return sdf_mesh(sdf, (-1, -1, -1), (23.5, 11, 15), step)


def standing_lens(rim_radius=10.0, half_angle_deg=40.0, step=0.1):
    """:func:`lens` stood on its rim on a 2 mm base plate (so a slicer has a first layer): the
    rim in the plane y = 0, the lens centred at (0, 0, rim_radius + 1), the base z = 0..2."""
    a = np.radians(half_angle_deg)
    big = rim_radius / np.sin(a)
    off = big * np.cos(a)
    centre = np.array([0.0, 0.0, rim_radius + 1.0])

    def sdf(p):
        q = p - centre
        caps = np.maximum(np.linalg.norm(q - [0, -off, 0], axis=1), np.linalg.norm(q + [0, -off, 0], axis=1)) - big
        return np.minimum(caps, box_sdf(p, (-4, -4, 0), (4, 4, 2)))

    h = big - off + step
    return sdf_mesh(sdf, (-rim_radius - 1, -h, -0.5), (rim_radius + 1, h, 2 * rim_radius + 2), step)
