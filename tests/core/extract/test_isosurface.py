"""isosurface(): watertight marching cubes — the case table, analytic shapes, noise, real CT."""
import math

import numpy as np
import pytest

from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.extract import mc_table
from anatomesh.core.extract.isosurface import T_MIN, isosurface, isosurfaces
from anatomesh.core.io.load import load
from anatomesh.core.model.mesh import degenerate_faces, duplicate_vertices, signed_volume, surface_area
from anatomesh.core.geometry.topology import edge_face_counts, topology
from anatomesh.core.model.volume import Volume
from conftest import shared

# ---------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------
SPACING = (0.8, 1.1, 1.7)


def rotation(ax, ay, az):
    cx, sx, cy, sy, cz, sz = (math.cos(ax), math.sin(ax), math.cos(ay), math.sin(ay),
                              math.cos(az), math.sin(az))
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def sample(field, half_extent, spacing=SPACING, rot=np.eye(3), flip_axis=None):
    """Sample ``field(x, y, z)`` (mm) on a grid with affine rot @ diag(spacing) covering the box
    [-half_extent, half_extent]^3 (any rotation); returns (values float64 (I,J,K), affine)."""
    lin = rot @ np.diag(spacing)
    if flip_axis is not None:
        lin[:, flip_axis] *= -1
    # index range that covers the box: corners of the box in index space
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half_extent
    idx = np.linalg.solve(lin, corners.T).T
    lo, hi = np.floor(idx.min(0)) - 1, np.ceil(idx.max(0)) + 1
    shape = (hi - lo + 1).astype(int)
    aff = np.eye(4)
    aff[:3, :3] = lin
    aff[:3, 3] = lin @ lo
    ii = np.indices(shape).reshape(3, -1).astype(float)
    world = aff[:3, :3] @ ii + aff[:3, 3:4]
    vals = field(*world).reshape(shape)
    return vals, aff


def sphere(r):
    return lambda x, y, z: r - np.sqrt(x * x + y * y + z * z)


def ellipsoid(a, b, c):
    # radial scaling of the normalised distance: smooth, nearly linear across the surface
    return lambda x, y, z: min(a, b, c) * (1 - np.sqrt((x / a) ** 2 + (y / b) ** 2 + (z / c) ** 2))


def torus(big, small, cx=0.0):
    return lambda x, y, z: small - np.sqrt((np.sqrt((x - cx) ** 2 + y * y) - big) ** 2 + z * z)


def ellipsoid_area(a, b, c, n=400):
    """Surface area of an ellipsoid by Gauss–Legendre quadrature (numpy only)."""
    t, wt = np.polynomial.legendre.leggauss(n)
    th = (t + 1) * np.pi / 2
    ph = (t + 1) * np.pi
    th, ph = np.meshgrid(th, ph, indexing="ij")
    st, ct, sp, cp = np.sin(th), np.cos(th), np.sin(ph), np.cos(ph)
    integrand = st * np.sqrt((b * c * st * cp) ** 2 + (a * c * st * sp) ** 2 + (a * b * ct) ** 2)
    return float(np.einsum("i,j,ij", wt, wt, integrand) * (np.pi / 2) * np.pi)


def check_watertight(mesh, genus=None):
    topo = topology(mesh.vertices, mesh.faces)
    assert topo.closed and topo.manifold and topo.oriented, topo
    assert topo.degenerate_faces == 0, topo
    if genus is not None:
        assert topo.genus == genus, topo
    assert signed_volume(mesh.vertices, mesh.faces) > 0
    return topo


def normal_agreement(mesh):
    """Mean cosine between each face normal and the mean of its vertex normals."""
    v, f, n = mesh.vertices.astype(float), mesh.faces, mesh.normals.astype(float)
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    vn = n[f].sum(axis=1)
    vn /= np.linalg.norm(vn, axis=1, keepdims=True)
    return float(np.mean(np.einsum("ij,ij->i", fn, vn)))


def check_mesh_arrays(mesh):
    assert mesh.vertices.dtype == np.float32 and mesh.vertices.shape[1] == 3
    assert mesh.faces.dtype == np.int32 and mesh.faces.shape[1] == 3
    assert mesh.normals.shape == mesh.vertices.shape
    assert np.all(np.isfinite(mesh.vertices)) and np.all(np.isfinite(mesh.normals))
    if mesh.n_vertices:
        assert np.allclose(np.linalg.norm(mesh.normals, axis=1), 1, atol=1e-5)
        assert mesh.faces.min() >= 0 and mesh.faces.max() < mesh.n_vertices
        assert np.unique(mesh.faces).size == mesh.n_vertices  # every vertex is used


OBLIQUE = rotation(0.3, -0.5, 0.8)


# ---------------------------------------------------------------------------------------------
# the case table
# ---------------------------------------------------------------------------------------------
def test_table_properties():
    mc_table.check_table(mc_table.TRI_COUNT, mc_table.TRI_EDGES, mc_table.EDGE_MASK)
    assert mc_table.TRI_COUNT[0] == 0 and mc_table.TRI_COUNT[255] == 0
    assert mc_table.TRI_COUNT[1] == 1  # one corner above: one triangle


def test_table_faces_agree_between_neighbours():
    """A face seen from the two cells sharing it gets the same segments, reversed."""
    # face x=1 of the left cell is face x=0 of the right cell: corner dx=1 ↔ dx=0
    for left in range(256):
        for right_hi in range(16):  # the right cell's far corners do not matter for this face
            face_bits = [(left >> c) & 1 for c in (1, 3, 5, 7)]  # left cell's x=1 corners
            right = sum(b << c for b, c in zip(face_bits, (0, 2, 4, 6)))
            right |= sum(((right_hi >> i) & 1) << c for i, c in enumerate((1, 3, 5, 7)))
            segs_l = {(a, b) for f, a, b in mc_table.face_segments(left) if f == 1}
            segs_r = {(a, b) for f, a, b in mc_table.face_segments(right) if f == 0}
            # x-edges do not lie on x faces; y/z edges at dx=1 (left) are at dx=0 (right): e-1
            moved = {(b - 1, a - 1) for a, b in segs_l}
            assert moved == segs_r, (left, right)


# ---------------------------------------------------------------------------------------------
# analytic shapes on anisotropic and oblique grids
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("rot", [np.eye(3), OBLIQUE], ids=["axis-aligned", "oblique"])
def test_sphere_area_volume(rot):
    r = 18.0
    vals, aff = sample(sphere(r), r + 3, rot=rot)
    mesh = isosurface(vals, 0.0, affine=aff)
    check_mesh_arrays(mesh)
    check_watertight(mesh, genus=0)
    area, vol = surface_area(mesh.vertices, mesh.faces), signed_volume(mesh.vertices, mesh.faces)
    assert area == pytest.approx(4 * np.pi * r * r, rel=0.01)
    assert vol == pytest.approx(4 / 3 * np.pi * r ** 3, rel=0.005)
    assert normal_agreement(mesh) > 0.99
    # normals point outwards: along the radius
    radial = mesh.vertices / np.linalg.norm(mesh.vertices, axis=1, keepdims=True)
    assert np.mean(np.einsum("ij,ij->i", radial, mesh.normals)) > 0.999


def test_ellipsoid_area_volume():
    a, b, c = 24.0, 18.0, 12.0  # the volume error of MC grows like (spacing / radius)^2
    vals, aff = sample(ellipsoid(a, b, c), a + 3, rot=OBLIQUE)
    mesh = isosurface(vals, 0.0, affine=aff)
    check_watertight(mesh, genus=0)
    assert surface_area(mesh.vertices, mesh.faces) == pytest.approx(ellipsoid_area(a, b, c), rel=0.01)
    assert signed_volume(mesh.vertices, mesh.faces) == pytest.approx(4 / 3 * np.pi * a * b * c, rel=0.005)
    assert normal_agreement(mesh) > 0.99


def test_torus_genus_area_volume():
    big, small = 20.0, 9.0
    vals, aff = sample(torus(big, small), big + small + 3, rot=OBLIQUE)
    mesh = isosurface(vals, 0.0, affine=aff)
    check_watertight(mesh, genus=1)
    assert surface_area(mesh.vertices, mesh.faces) == pytest.approx(4 * np.pi ** 2 * big * small, rel=0.01)
    assert signed_volume(mesh.vertices, mesh.faces) == pytest.approx(2 * np.pi ** 2 * big * small ** 2,
                                                                     rel=0.005)
    assert normal_agreement(mesh) > 0.99


def test_double_torus_genus():
    t1, t2 = torus(9.0, 3.0, cx=-8.0), torus(9.0, 3.0, cx=8.0)
    vals, aff = sample(lambda x, y, z: np.maximum(t1(x, y, z), t2(x, y, z)), 22.0, rot=OBLIQUE)
    mesh = isosurface(vals, 0.0, affine=aff)
    topo = check_watertight(mesh, genus=2)
    assert topo.components == 1


def test_negative_determinant_affine_keeps_outward_orientation():
    r = 10.0
    for flip_axis in (0, 2):
        vals, aff = sample(sphere(r), r + 3, flip_axis=flip_axis)
        assert np.linalg.det(aff[:3, :3]) < 0
        mesh = isosurface(vals, 0.0, affine=aff)
        check_watertight(mesh, genus=0)
        assert signed_volume(mesh.vertices, mesh.faces) == pytest.approx(4 / 3 * np.pi * r ** 3, rel=0.01)
        assert normal_agreement(mesh) > 0.99
    # LPS volume asked in RAS: x and y negated (determinant unchanged), still outward
    vol = Volume(vals, aff, "LPS")
    ras = isosurface(vol, 0.0, space="RAS")
    lps = isosurface(vol, 0.0)
    assert ras.space == "RAS" and lps.space == "LPS"
    np.testing.assert_allclose(ras.vertices[:, :2], -lps.vertices[:, :2], atol=1e-5)
    assert signed_volume(ras.vertices, ras.faces) > 0


def test_memory_order_gives_the_same_surface():
    vals, aff = sample(torus(8.0, 3.0), 13.0, rot=OBLIQUE)
    c = isosurface(np.ascontiguousarray(vals), 0.0, affine=aff)
    f = isosurface(np.asfortranarray(vals), 0.0, affine=aff)
    s = isosurface(vals.transpose(1, 2, 0).copy().transpose(2, 0, 1), 0.0, affine=aff)  # odd strides
    for other in (f, s):
        assert other.n_vertices == c.n_vertices and other.n_faces == c.n_faces
        np.testing.assert_allclose(np.sort(other.vertices, axis=0), np.sort(c.vertices, axis=0), atol=1e-4)
        # the same vertices; a loop may be split along other diagonals (the table's frame is
        # the sweep axis order), so volumes agree only to the diagonals' rounding
        assert signed_volume(other.vertices, other.faces) == pytest.approx(
            signed_volume(c.vertices, c.faces), rel=1e-3)
        check_watertight(other, genus=1)


def test_several_levels_in_one_pass_match_single_calls():
    vals, aff = sample(sphere(9.0), 12.0)
    both = isosurfaces(Volume(vals, aff, "RAS"), [0.0, 3.0])
    for lv, mesh in zip((0.0, 3.0), both):
        single = isosurface(vals, lv, affine=aff)
        assert mesh.value == lv
        np.testing.assert_array_equal(mesh.faces, single.faces)
        np.testing.assert_array_equal(mesh.vertices, single.vertices)
    assert signed_volume(both[1].vertices, both[1].faces) < signed_volume(both[0].vertices, both[0].faces)


def test_output_does_not_depend_on_the_thread_count():
    import numba

    vals, aff = sample(torus(8.0, 3.0), 13.0, rot=OBLIQUE)
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = isosurface(vals, 0.0, affine=aff, cap=True)
    finally:
        numba.set_num_threads(before)
    many = isosurface(vals, 0.0, affine=aff, cap=True)
    np.testing.assert_array_equal(one.faces, many.faces)
    np.testing.assert_array_equal(one.vertices, many.vertices)
    np.testing.assert_array_equal(one.normals, many.normals)


# ---------------------------------------------------------------------------------------------
# random fields: the consistency proof of the table
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(4))
def test_random_noise_is_closed_manifold_oriented(seed):
    rng = np.random.default_rng(seed)
    vals = rng.normal(size=(24, 23, 25))
    mesh = isosurface(vals, 0.3 * (seed % 3 - 1), cap=True)
    check_mesh_arrays(mesh)
    topo = check_watertight(mesh)
    assert topo.faces > 1000
    assert duplicate_vertices(mesh.vertices).size == 0
    open_mesh = isosurface(vals, 0.3 * (seed % 3 - 1))  # uncapped: manifold, boundary only on the border
    t2 = topology(open_mesh.vertices, open_mesh.faces)
    assert t2.manifold and t2.oriented and t2.boundary_edges > 0


@pytest.mark.parametrize("seed", range(3))
def test_random_integers_at_an_integer_level(seed):
    """Many voxels equal to the level: no zero-area face, no duplicate vertex, closed."""
    rng = np.random.default_rng(100 + seed)
    vals = rng.integers(0, 4, size=(22, 24, 20)).astype(np.int16)
    mesh = isosurface(vals, 2, cap=True)
    check_mesh_arrays(mesh)
    check_watertight(mesh)
    assert degenerate_faces(mesh.vertices, mesh.faces).size == 0
    assert duplicate_vertices(mesh.vertices).size == 0
    # vertices sit T_MIN from a voxel centre when the voxel equals the level
    frac = np.abs(mesh.vertices - np.round(mesh.vertices))
    assert frac[frac > 0].min() >= T_MIN * 0.99


def reference_triangles(vals, level):
    """Each cell's triangles straight from the case table, as triples of edge keys
    (i, j, k, axis) in array index space: what the kernels must produce, cell by cell."""
    above = vals >= level
    out = []
    for i in range(vals.shape[0] - 1):
        for j in range(vals.shape[1] - 1):
            for k in range(vals.shape[2] - 1):
                # table corner c is at kernel frame offset (dx, dy, dz) = array offset (dz, dy, dx)
                case = sum(int(above[i + dz, j + dy, k + dx]) << c
                           for c, (dx, dy, dz) in enumerate(mc_table.CORNERS))
                keys = []
                for e in mc_table.TRI_EDGES[case][:3 * mc_table.TRI_COUNT[case]]:
                    c0, c1 = mc_table.EDGE_CORNERS[e]
                    d0, d1 = mc_table.CORNERS[c0], mc_table.CORNERS[c1]
                    axis = 2 - int(np.argmax(d1 != d0))  # frame axis x, y, z = array axis 2, 1, 0
                    keys.append((i + d0[2], j + d0[1], k + d0[0], axis))
                out += [tuple(keys[t:t + 3]) for t in range(0, len(keys), 3)]
    return out


def canonical(tri):
    """A triangle's cyclic rotation starting at its smallest key (keeps the winding)."""
    r = tri.index(min(tri))
    return tri[r:] + tri[:r]


@pytest.mark.parametrize("kind", ["float", "integer-ties"])
def test_triangles_match_the_case_table_cell_by_cell(kind):
    """Every cell's triangles, vertices and winding are the table's (rows span three 64-bit
    words, so word boundaries and each slab's last cells are crossed)."""
    rng = np.random.default_rng(7)
    if kind == "float":
        vals, level = rng.normal(size=(7, 8, 150)), 0.2
    else:
        vals, level = rng.integers(0, 3, size=(7, 8, 150)).astype(np.int16), 1
    mesh = isosurface(vals, level)  # identity affine: vertices in array index coordinates
    p = mesh.vertices.astype(np.float64)
    frac = np.abs(p - np.round(p))
    axis = np.argmax(frac, axis=1)
    assert np.all(frac.max(axis=1) >= T_MIN * 0.99)  # every vertex strictly inside its edge
    low = np.round(p).astype(int)
    rows = np.arange(len(p))
    low[rows, axis] = np.floor(p[rows, axis]).astype(int)
    keys = [tuple(low[v]) + (int(axis[v]),) for v in range(len(p))]
    assert len(set(keys)) == len(keys)  # one vertex per crossed edge
    got = sorted(canonical(tuple(keys[v] for v in f)) for f in mesh.faces)
    # the frame (x, y, z) = array axes (2, 1, 0) reverses orientation: the table's winding flips
    want = sorted(canonical((a, c, b)) for a, b, c in reference_triangles(vals, level))
    assert len(got) == len(want) and got == want


# ---------------------------------------------------------------------------------------------
# real scans
# ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def head_ct():
    return load(shared("slicer_ctheadaxial"))


@pytest.fixture(scope="module")
def chest_ct():
    return load(shared("itkelastix_chest_ct"))


@pytest.mark.parametrize("level", [500, 1150], ids=["skin", "bone"])
def test_head_ct_surfaces_closed_with_cap(head_ct, level):
    mesh = isosurface(head_ct, level, cap=True)
    check_mesh_arrays(mesh)
    topo = check_watertight(mesh)
    assert topo.faces > 10000
    assert mesh.space == head_ct.space
    # inside the scan's bounding box (caps lie T_MIN voxel outside the border centres)
    corners = np.array([[i, j, k, 1] for i in (-0.01, head_ct.shape[0] - 0.99)
                        for j in (-0.01, head_ct.shape[1] - 0.99) for k in (-0.01, head_ct.shape[2] - 0.99)])
    world = (head_ct.affine @ corners.T).T[:, :3]
    assert np.all(mesh.vertices >= world.min(0) - 1e-3) and np.all(mesh.vertices <= world.max(0) + 1e-3)


@pytest.mark.parametrize("level", [300, -500], ids=["bone", "skin"])
def test_chest_ct_integer_level_no_degenerate_faces(chest_ct, level):
    """512x512x141 int16 CT at an integer HU: many voxels equal the level."""
    assert chest_ct.data.dtype.kind in "iu"
    assert np.count_nonzero(chest_ct.data == level) > 1000
    open_mesh = isosurface(chest_ct, level)
    assert open_mesh.n_faces > 500_000
    assert degenerate_faces(open_mesh.vertices, open_mesh.faces).size == 0  # area > 0
    assert duplicate_vertices(open_mesh.vertices).size == 0
    capped = isosurface(chest_ct, level, cap=True)
    assert capped.n_faces > open_mesh.n_faces
    if level == 300:  # the full check (vertex fans too) takes 4 s on 1 M faces: bone only
        check_watertight(capped)
    else:  # closed and consistently oriented: every edge has two faces, one in each direction
        _, count, balance = edge_face_counts(capped.faces, capped.n_vertices)
        assert np.all(count == 2) and np.all(balance == 0)
        assert signed_volume(capped.vertices, capped.faces) > 0


@pytest.mark.parametrize("level", [-500, 300], ids=["skin", "bone"])
def test_cap_changes_nothing_away_from_the_border(chest_ct, level):
    """The vertex writer has a copy specialised for capping (border checks) and one without:
    on a surface that never reaches the border both must give the very same bits."""
    block = chest_ct.data[150:230, 180:300, 30:110]
    vals = np.pad(block, 1, constant_values=-1024)  # air all around: nothing touches the border
    open_mesh = isosurface(vals, level, affine=chest_ct.affine)
    capped = isosurface(vals, level, affine=chest_ct.affine, cap=True)
    assert open_mesh.n_faces > 4_000
    np.testing.assert_array_equal(open_mesh.vertices, capped.vertices)
    np.testing.assert_array_equal(open_mesh.normals, capped.normals)
    np.testing.assert_array_equal(open_mesh.faces, capped.faces)


# ---------------------------------------------------------------------------------------------
# inputs
# ---------------------------------------------------------------------------------------------
def test_bad_inputs_raise_clear_errors():
    with pytest.raises(AnatomeshError, match="3D"):
        isosurface(np.zeros((4, 4)), 0.5)
    with pytest.raises(AnatomeshError, match="3D"):
        isosurface(np.zeros((2, 4, 4, 4)), 0.5)
    with pytest.raises(AnatomeshError, match="not finite"):
        isosurface(np.zeros((4, 4, 4)), float("nan"))
    with pytest.raises(AnatomeshError, match="not a number"):
        isosurface(np.zeros((4, 4, 4)), "300")
    with pytest.raises(AnatomeshError, match="real numbers"):
        isosurface(np.zeros((4, 4, 4), complex), 0.5)
    with pytest.raises(AnatomeshError, match="singular"):
        isosurface(np.zeros((4, 4, 4)), 0.5, affine=np.diag([1.0, 0.0, 1.0, 1.0]))
    with pytest.raises(AnatomeshError, match="4x4"):
        isosurface(np.zeros((4, 4, 4)), 0.5, affine=np.eye(3))
    with pytest.raises(AnatomeshError, match="no isovalue"):
        isosurfaces(np.zeros((4, 4, 4)), [])
    with pytest.raises(AnatomeshError, match="not a number"):
        isosurfaces(np.zeros((4, 4, 4)), [1.0, 2j])
    with pytest.raises(AnatomeshError, match="space"):
        isosurface(np.zeros((4, 4, 4)), 0.5, space="XYZ")
    # levels as a numpy array are fine
    vals = np.zeros((5, 5, 5))
    vals[2, 2, 2] = 1
    assert [m.n_faces for m in isosurfaces(vals, np.array([0.5, 2.0]))] == [8, 0]


def test_nan_voxels_count_as_below():
    vals, aff = sample(sphere(8.0), 11.0)
    holey = vals.copy()
    holey[holey.shape[0] // 2:, :, :] = np.nan  # half the volume is missing
    mesh = isosurface(holey, 0.0, affine=aff, cap=True)
    check_mesh_arrays(mesh)
    check_watertight(mesh, genus=0)
    whole = isosurface(vals, 0.0, affine=aff)
    full = signed_volume(whole.vertices, whole.faces)
    assert 0.3 * full < signed_volume(mesh.vertices, mesh.faces) < 0.7 * full


def test_levels_outside_the_range_and_tiny_volumes_give_empty_meshes():
    vals = np.random.default_rng(0).integers(0, 100, size=(6, 7, 8)).astype(np.uint8)
    for level in (-5, 0, 100, 1e9, -1e9):  # 0: every voxel is above (>= 0)
        for cap in (False, True):
            m = isosurface(vals, level, cap=cap)
            assert m.n_vertices == 0 and m.n_faces == 0 and m.value == level
    assert isosurface(np.zeros((0, 5, 5)), 0.5).n_faces == 0
    assert isosurface(np.ones((1, 5, 5)), 0.5).n_faces == 0  # no cells without a cap
    slab = np.zeros((1, 6, 6))
    slab[0, 2:4, 2:4] = 1
    capped = isosurface(slab, 0.5, cap=True)  # a single slice is capped into a closed sheet
    check_watertight(capped, genus=0)
    line = np.zeros((1, 1, 6))
    line[0, 0, 2:4] = 1
    check_watertight(isosurface(line, 0.5, cap=True), genus=0)
    bools = np.zeros((5, 5, 5), bool)
    bools[1:4, 1:4, 1:4] = True
    check_watertight(isosurface(bools, 0.5), genus=0)


def test_progress_is_reported():
    seen = []
    isosurfaces(np.random.default_rng(1).normal(size=(8, 8, 8)), [0.0, 0.5],
                progress=lambda f, t: seen.append(f))
    assert seen[0] == 0.0 and seen[-1] == 1.0 and seen == sorted(seen)
