"""Analytic volumes for preprocessing tests: coordinate grids in mm, sphere and torus fields and
label maps, and the distance of surface samples to the analytic shape."""
import numpy as np

from anatomesh.core.geometry.measure import sample_points
from anatomesh.core.model.labels import LabelInfo
from anatomesh.core.model.volume import Volume


def grid(shape, spacing):
    """(x, y, z) mm coordinates of the voxel centres (centred on 0) and the matching affine."""
    sp = np.asarray(spacing, float)
    c = (np.asarray(shape) - 1) / 2.0
    ijk = np.indices(shape).astype(float)
    xyz = [(ijk[a] - c[a]) * sp[a] for a in range(3)]
    affine = np.diag([*sp, 1.0])
    affine[:3, 3] = -c * sp
    return xyz, affine


def sphere_distance(points, radius):
    return np.abs(np.linalg.norm(points, axis=1) - radius)


def standing_torus(points, R, r):
    """Distance to the torus of radii R (ring) and r (tube) around the x axis."""
    q = np.sqrt(points[:, 1] ** 2 + points[:, 2] ** 2) - R
    return np.abs(np.sqrt(q ** 2 + points[:, 0] ** 2) - r)


def mean_error(mesh, distance, *args):
    """Mean distance (mm) of a mesh's samples (vertices + face centroids) to an analytic shape."""
    return float(distance(sample_points(mesh.vertices, mesh.faces), *args).mean())


def label_volume(mask, affine, name="shape", value=1):
    return Volume(np.asarray(mask, np.uint8) * np.uint8(value), affine, "RAS",
                  labels={value: LabelInfo(value, name)})


def torus_labels(R=15.0, r=6.0, spacing=(0.5, 0.5, 5.0)):
    """A standing torus (axis x) as a label map: the thick slices cut across its ring."""
    sp = np.asarray(spacing)
    shape = (int(2 * r / sp[0]) + 12, int(2 * (R + r) / sp[1]) + 12, int(2 * (R + r) / sp[2]) + 4)
    (x, y, z), affine = grid(shape, sp)
    mask = (np.sqrt(y ** 2 + z ** 2) - R) ** 2 + x ** 2 <= r ** 2
    return label_volume(mask, affine, "torus")


def cross_sections(mesh, step=0.5):
    """Area (mm²) of a closed, outward-oriented mesh's cross-section every ``step`` mm along z:
    each triangle the plane cuts gives a segment, oriented by the face normal, and the segments'
    shoelace sum is the enclosed area. A staircase of thick slices shows as jumps."""
    v = mesh.vertices.astype(np.float64)
    f = mesh.faces
    tri = v[f]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    out = []
    for z in np.arange(v[:, 2].min() + step / 2, v[:, 2].max(), step):
        above = tri[:, :, 2] > z
        cut = above.any(axis=1) & ~above.all(axis=1)
        t, n = tri[cut], normal[cut]
        pts = []
        for a, b in ((0, 1), (1, 2), (2, 0)):
            crosses = (t[:, a, 2] > z) != (t[:, b, 2] > z)
            w = np.where(crosses, (z - t[:, a, 2]) / np.where(crosses, t[:, b, 2] - t[:, a, 2], 1.0), np.nan)
            pts.append(t[:, a, :2] + w[:, None] * (t[:, b, :2] - t[:, a, :2]))
        pts = np.stack(pts, 1)  # two of the three are finite
        first = np.argsort(np.isnan(pts[:, :, 0]), axis=1, kind="stable")  # the finite two first
        rows = np.arange(len(pts))
        p, q = pts[rows, first[:, 0]], pts[rows, first[:, 1]]
        d = q - p
        flip = d[:, 0] * n[:, 1] - d[:, 1] * n[:, 0] > 0  # orient: outward normal on the right
        p, q = np.where(flip[:, None], q, p), np.where(flip[:, None], p, q)
        out.append(0.5 * abs(np.sum(p[:, 0] * q[:, 1] - p[:, 1] * q[:, 0])))
    return np.array(out, float)


def largest_jump(profile):
    """The largest change between neighbouring cross-sections, as a fraction of the largest."""
    return float(np.abs(np.diff(profile)).max() / profile.max())
