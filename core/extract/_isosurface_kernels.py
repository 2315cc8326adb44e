"""Numba kernels of :func:`anatomesh.core.extract.isosurface` (flying-edges style marching cubes).

Kernel frame: the array ``v`` has shape ``(nz, ny, nx)`` and its last axis ``x`` is the one
contiguous in memory. A *row* is ``v[z, y, :]``. With ``pad = 1`` (capping) the kernels see a
virtual grid one voxel larger on every side whose outside samples are below the level; virtual
index ``X = x + pad`` (same for Y, Z). Nothing is copied: outside samples only exist as zero bits.

Passes (after Schroeder, Maynard and Geveci 2015, "Flying Edges: A High-Performance Scalable
Isocontouring Algorithm", IEEE LDAV; their per-row trim ranges are replaced by bit masks, which
skip empty space 64 voxels per machine word and never re-read the data there):

1. :func:`classify` — the only pass over all the data: each row is read once from memory and,
   while it is in cache, packed into one bit per voxel (``value >= threshold``) for every level.
2. :func:`count` — from the bit masks only: per grid row the crossed x-, y- and z-edges
   (popcounts of XORs), per cell row the triangles of its active cells (cells whose 8 corner bits
   are not all equal, found 64 at a time); per z-slab the totals.
3. a prefix sum over the slabs (in the wrapper) gives each slab its first vertex and triangle, so
   the output does not depend on the thread count; :func:`emit_vertices` interpolates one vertex
   per crossed edge (position, normal from the central-difference gradient) and
   :func:`emit_triangles` writes the triangles, finding the vertex of each cell edge by counting
   the crossed edges to its left with popcounts.

Vertex order: slab by slab, grid row by grid row; within grid row ``(Z, Y)`` its crossed x-edges
(in x order), then its crossed y-edges to row ``(Z, Y+1)``, then its crossed z-edges to row
``(Z+1, Y)``. Each slab is processed by one thread; work is split over slabs with ``prange``.

Performance notes: each parallel kernel only calls a serial per-slab function (numba's parfor
lowering is slow to compile; small hot helpers are inlined at numba level because LLVM does not
inline across numba functions); the loops index arrays directly instead of taking row views (a
view bumps the parent's reference count atomically, which stalls two threads sharing it); the
prange index is passed on as int64 (numba may type it unsigned, and unsigned + signed → float).
The triangle writer copies a fixed 15 table entries per cell (unrolled, unsigned indices) and
lets the next cell overwrite the excess, instead of a loop whose data-dependent exit the branch
predictor misses once per cell. The vertex writer runs one loop over a run-time axis, with
capping a run-time flag, around one inlined copy of :func:`_vertex`: a loop per literal axis,
specialised without capping, makes that pass a little quicker, but each specialised copy adds
much compile time on a cold cache (the first run). Endpoint gradients are computed per edge, not
shared between edges through per-slab row buffers (which saves evaluations but is slower):
inline, the gradient loads overlap with the division and square-root latency of each vertex; in
a pass of their own they do not, and the buffer traffic comes on top.
"""
from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, prange, types
from numba.extending import intrinsic, overload

# error_model="numpy": a division by zero gives inf/nan (handled) instead of raising
_parallel = njit(cache=True, parallel=True, error_model="numpy")  # prange over slabs
_serial = njit(cache=True, error_model="numpy")  # the work of one slab
_inline = njit(cache=True, inline="always", error_model="numpy")  # small hot helpers

_ONE = np.uint64(1)
_ALL = np.uint64(0xFFFFFFFFFFFFFFFF)
_S63 = np.uint64(63)


# Bit helpers: LLVM intrinsics in a kernel (single instructions, no numba-level inlining to
# compile), plain integer arithmetic outside numba (the warm-up's lanes run kernels as Python).
def _pc(x):
    """Number of set bits of a uint64, as int64 (LLVM ctpop: one POPCNT instruction)."""
    return np.int64(bin(int(x)).count("1"))


def _ctz(x):
    """Index of the lowest set bit of a non-zero uint64, as int64 (LLVM cttz)."""
    return np.int64((int(x) & -int(x)).bit_length() - 1)


def _bit(w, b):
    """Bit b (0..63) of the uint64 w, as int64 0 or 1."""
    return np.int64((int(w) >> int(b)) & 1)


def _low_mask(b):
    """uint64 with bits 0 .. b-1 set (b in 0..63)."""
    return np.uint64((1 << int(b)) - 1)


@intrinsic
def _llvm_pc(typingctx, x):
    if x != types.uint64:
        return None

    def codegen(context, builder, sig, args):
        return builder.ctpop(args[0])

    return types.int64(types.uint64), codegen


@intrinsic
def _llvm_ctz(typingctx, x):
    if x != types.uint64:
        return None

    def codegen(context, builder, sig, args):
        return builder.cttz(args[0], ir.Constant(ir.IntType(1), 1))

    return types.int64(types.uint64), codegen


@intrinsic
def _llvm_bit(typingctx, w, b):
    if w != types.uint64 or not isinstance(b, types.Integer):
        return None

    def codegen(context, builder, sig, args):
        shift = context.cast(builder, args[1], sig.args[1], types.uint64)
        return builder.and_(builder.lshr(args[0], shift), ir.Constant(ir.IntType(64), 1))

    return types.int64(w, b), codegen


@intrinsic
def _llvm_low_mask(typingctx, b):
    if not isinstance(b, types.Integer):
        return None

    def codegen(context, builder, sig, args):
        one = ir.Constant(ir.IntType(64), 1)
        shift = context.cast(builder, args[0], sig.args[0], types.uint64)
        return builder.sub(builder.shl(one, shift), one)

    return types.uint64(b), codegen


# in a kernel, each helper above is its intrinsic
overload(_pc)(lambda x: lambda x: _llvm_pc(x))
overload(_ctz)(lambda x: lambda x: _llvm_ctz(x))
overload(_bit)(lambda w, b: lambda w, b: _llvm_bit(w, b))
overload(_low_mask)(lambda b: lambda b: _llvm_low_mask(b))


# ---------------------------------------------------------------------------------------------
# pass 1: bit masks
# ---------------------------------------------------------------------------------------------
@_inline
def _pack_word(v, z, y, x0, t):
    """Bits ``v[z, y, x0 + b] >= t`` for b = 0..63 (the whole word inside the row)."""
    w = np.uint64(0)
    for b in range(64):
        w |= np.uint64(v[z, y, x0 + b] >= t) << np.uint64(b)
    return w


@_inline
def _pack_word_checked(v, z, y, x0, t):
    """Like _pack_word for a word that runs past either end of the row (outside bits are 0)."""
    w = np.uint64(0)
    for x in range(max(x0, 0), min(x0 + 64, v.shape[2])):
        w |= np.uint64(v[z, y, x] >= t) << np.uint64(x - x0)
    return w


@_parallel
def classify(v, thresholds, pad, bits, n_above):
    """Pack ``v >= thresholds[l]`` into ``bits[l, Z, Y, :]`` (bit X of word X // 64).

    v : (nz, ny, nx) any real dtype; thresholds : (L,) same dtype as v.
    bits : (L, nz + 2 pad, ny + 2 pad, W) uint64, zero-filled by the caller (pad rows stay 0).
    n_above : (L, nz) int64 out, voxels above per slab (to spot levels outside the data range).
    """
    for z in prange(v.shape[0]):
        _classify_slab(v, thresholds, pad, bits, n_above, np.int64(z))


@_serial
def _classify_slab(v, thresholds, pad, bits, n_above, z):
    nx = v.shape[2]
    n_words = bits.shape[3]
    for y in range(v.shape[1]):
        for lv in range(thresholds.shape[0]):  # the row stays in cache for every level
            t = thresholds[lv]
            n = 0
            for wi in range(n_words):
                x0 = wi * 64 - pad
                if x0 >= 0 and x0 + 64 <= nx:
                    w = _pack_word(v, z, y, x0, t)
                else:
                    w = _pack_word_checked(v, z, y, x0, t)
                bits[lv, z + pad, y + pad, wi] = w
                n += _pc(w)
            n_above[lv, z] += n


# ---------------------------------------------------------------------------------------------
# pass 2: counts
# ---------------------------------------------------------------------------------------------
@_inline
def _shift1(bits, kz, jy, wi, n_words):
    """Word wi of row (kz, jy) shifted by one voxel: bit X of the result = bit X+1 of the row."""
    nxt = bits[kz, jy, wi + 1] if wi + 1 < n_words else np.uint64(0)
    return (bits[kz, jy, wi] >> _ONE) | (nxt << _S63)


@_inline
def _last_mask(nx_virtual, n_words):
    """Mask of the valid cell / x-edge positions X <= NX - 2 in the last word."""
    rem = (nx_virtual - 1) - 64 * (n_words - 1)
    if rem >= 64:
        return _ALL
    return _low_mask(rem)


@_inline
def _case(r00, s00, r10, s10, r01, s01, r11, s11, b):
    """Case index of the cell at bit b: corner dx + 2 dy + 4 dz (r: x = X, s: x = X + 1)."""
    return (_bit(r00, b) | (_bit(s00, b) << 1) | (_bit(r10, b) << 2) | (_bit(s10, b) << 3)
            | (_bit(r01, b) << 4) | (_bit(s01, b) << 5) | (_bit(r11, b) << 6) | (_bit(s11, b) << 7))


@_parallel
def count(bits, nx_virtual, tri_count, n_xe, n_ye, n_ze, n_tri, slab_vertices, slab_triangles):
    """Crossed edges per grid row, triangles per cell row, and both per slab (one level).

    bits : (NZ, NY, W) uint64. Outputs (NZ, NY) int32: ``n_xe``, ``n_ye`` (edges to row Y+1),
    ``n_ze`` (edges to row Z+1), ``n_tri`` (cell row (Z, Y); zero on the last Y and Z);
    (NZ,) int64: ``slab_vertices``, ``slab_triangles``.
    """
    for kz in prange(bits.shape[0]):
        _count_slab(bits, nx_virtual, tri_count, n_xe, n_ye, n_ze, n_tri, slab_vertices,
                    slab_triangles, np.int64(kz))


@_serial
def _count_slab(bits, nx_virtual, tri_count, n_xe, n_ye, n_ze, n_tri, slab_vertices,
                slab_triangles, kz):
    nzv, nyv, n_words = bits.shape
    last = _last_mask(nx_virtual, n_words)
    k1 = min(kz + 1, nzv - 1)  # k1 == kz on the last slab: its z-differences are 0
    total_v, total_t = 0, 0
    for jy in range(nyv):
        j1 = min(jy + 1, nyv - 1)
        occupied = np.uint64(0)
        for wi in range(n_words):
            occupied |= bits[kz, jy, wi] | bits[kz, j1, wi] | bits[k1, jy, wi] | bits[k1, j1, wi]
        if occupied == 0:  # empty space (all four rows below the level): nothing to count
            n_xe[kz, jy] = 0
            n_ye[kz, jy] = 0
            n_ze[kz, jy] = 0
            n_tri[kz, jy] = 0
            continue
        cx, cy, cz = 0, 0, 0
        for wi in range(n_words):
            r00 = bits[kz, jy, wi]
            d = r00 ^ _shift1(bits, kz, jy, wi, n_words)
            if wi == n_words - 1:
                d &= last
            cx += _pc(d)
            cy += _pc(r00 ^ bits[kz, j1, wi])
            cz += _pc(r00 ^ bits[k1, jy, wi])
        n_xe[kz, jy] = cx
        n_ye[kz, jy] = cy
        n_ze[kz, jy] = cz
        total_v += cx + cy + cz
        if jy + 1 < nyv and kz + 1 < nzv:
            nt = 0
            for wi in range(n_words):
                r00, r10, r01, r11 = bits[kz, jy, wi], bits[kz, j1, wi], bits[k1, jy, wi], bits[k1, j1, wi]
                s00 = _shift1(bits, kz, jy, wi, n_words)
                s10 = _shift1(bits, kz, j1, wi, n_words)
                s01 = _shift1(bits, k1, jy, wi, n_words)
                s11 = _shift1(bits, k1, j1, wi, n_words)
                any_set = r00 | s00 | r10 | s10 | r01 | s01 | r11 | s11
                all_set = r00 & s00 & r10 & s10 & r01 & s01 & r11 & s11
                active = any_set & ~all_set
                if wi == n_words - 1:
                    active &= last
                while active:
                    b = _ctz(active)
                    active &= active - _ONE
                    nt += tri_count[_case(r00, s00, r10, s10, r01, s01, r11, s11, b)]
            n_tri[kz, jy] = nt
            total_t += nt
    slab_vertices[kz] = total_v
    slab_triangles[kz] = total_t


# ---------------------------------------------------------------------------------------------
# pass 3a: vertices
# ---------------------------------------------------------------------------------------------
@_inline
def _gradient(v, x, y, z):
    """Central-difference gradient (index units) at an in-grid voxel; one-sided at the border."""
    nz, ny, nx = v.shape
    xl, xh = max(x - 1, 0), min(x + 1, nx - 1)
    yl, yh = max(y - 1, 0), min(y + 1, ny - 1)
    zl, zh = max(z - 1, 0), min(z + 1, nz - 1)
    gx = (float(v[z, y, xh]) - float(v[z, y, xl])) * (0.5 if xh - xl == 2 else 1.0)
    gy = (float(v[z, yh, x]) - float(v[z, yl, x])) * (0.5 if yh - yl == 2 else 1.0)
    gz = (float(v[zh, y, x]) - float(v[zl, y, x])) * (0.5 if zh - zl == 2 else 1.0)
    return gx, gy, gz


@_inline
def _inside(x, y, z, nx, ny, nz):
    return 0 <= x < nx and 0 <= y < ny and 0 <= z < nz


@_inline
def _vertex(v, level, t_min, axis, x, y, z, m, n, out_v, out_n, idx, capping):
    """Write vertex ``idx`` on the edge from real voxel (x, y, z) one step along ``axis``.

    m : 12-tuple, row-major (3, 4) map table frame (x, y, z, 1) → mm; n : 9-tuple, row-major
    inverse transpose of its 3x3 part. With ``capping`` one endpoint may lie outside the grid:
    the vertex then sits ``t_min`` voxel from the inside endpoint, its normal points out of the
    grid; without it both endpoints are inside.
    """
    nz, ny, nx = v.shape
    dx = 1 if axis == 0 else 0
    dy = 1 if axis == 1 else 0
    dz = 1 if axis == 2 else 0
    x1, y1, z1 = x + dx, y + dy, z + dz
    in0 = _inside(x, y, z, nx, ny, nz) if capping else True
    in1 = _inside(x1, y1, z1, nx, ny, nz) if capping else True
    if in0 and in1:
        f0 = float(v[z, y, x])
        f1 = float(v[z1, y1, x1])
        t = (level - f0) / (f1 - f0)
        if t != t:  # NaN sample (counted as below): midpoint
            t = 0.5
        elif t < t_min:
            t = t_min
        elif t > 1.0 - t_min:
            t = 1.0 - t_min
        g0x, g0y, g0z = _gradient(v, x, y, z)
        g1x, g1y, g1z = _gradient(v, x1, y1, z1)
        gx = g0x + t * (g1x - g0x)
        gy = g0y + t * (g1y - g0y)
        gz = g0z + t * (g1z - g0z)
        if not (gx * gx + gy * gy + gz * gz > 1e-30):  # flat or NaN gradient: use the edge
            d = f1 - f0
            if not (abs(d) > 0.0 and abs(d) < 1e300):
                d = (1.0 if f1 >= level else -1.0) - (1.0 if f0 >= level else -1.0)
            gx, gy, gz = d * dx, d * dy, d * dz
        # normal = −gradient in mm (a covector: inverse transpose)
        nx_ = -(n[0] * gx + n[1] * gy + n[2] * gz)
        ny_ = -(n[3] * gx + n[4] * gy + n[5] * gz)
        nz_ = -(n[6] * gx + n[7] * gy + n[8] * gz)
    else:  # capping edge: the inside endpoint is above, the outside one below
        s = 1.0 if in0 else -1.0
        t = t_min if in0 else 1.0 - t_min
        nx_ = s * (n[0] * dx + n[1] * dy + n[2] * dz)
        ny_ = s * (n[3] * dx + n[4] * dy + n[5] * dz)
        nz_ = s * (n[6] * dx + n[7] * dy + n[8] * dz)
    px = x + t * dx
    py = y + t * dy
    pz = z + t * dz
    out_v[idx, 0] = m[0] * px + m[1] * py + m[2] * pz + m[3]
    out_v[idx, 1] = m[4] * px + m[5] * py + m[6] * pz + m[7]
    out_v[idx, 2] = m[8] * px + m[9] * py + m[10] * pz + m[11]
    inv = 1.0 / np.sqrt(nx_ * nx_ + ny_ * ny_ + nz_ * nz_)
    out_n[idx, 0] = nx_ * inv
    out_n[idx, 1] = ny_ * inv
    out_n[idx, 2] = nz_ * inv


@_parallel
def emit_vertices(v, bits, level, t_min, pad, m, n, n_xe, n_ye, n_ze, slab_start, out_v, out_n):
    """Pass 3a: one vertex per crossed edge; slab kz starts at vertex ``slab_start[kz]``."""
    for kz in prange(bits.shape[0]):
        _vertices_slab(v, bits, level, t_min, pad, m, n, n_xe, n_ye, n_ze, slab_start[kz], out_v,
                       out_n, np.int64(kz))


@_serial
def _vertices_slab(v, bits, level, t_min, pad, m, n, n_xe, n_ye, n_ze, idx, out_v, out_n, kz):
    """The vertices of slab kz from vertex ``idx`` on; with ``pad`` (a padded grid) an edge's
    endpoint may lie outside the grid (a capping edge). One loop over a run-time axis and one
    inlined vertex writer (compiles much faster than a loop per literal axis, with and without
    capping, at a small cost in run time)."""
    nzv, nyv, n_words = bits.shape
    last = _last_mask(v.shape[2] + 2 * pad, n_words)
    z = kz - pad
    k1 = min(kz + 1, nzv - 1)
    for jy in range(nyv):
        if n_xe[kz, jy] + n_ye[kz, jy] + n_ze[kz, jy] == 0:
            continue
        y = jy - pad
        j1 = min(jy + 1, nyv - 1)
        for axis in range(3):  # x-edges, then y-edges (to row Y+1), then z-edges (to row Z+1)
            ko = k1 if axis == 2 else kz
            jo = j1 if axis == 1 else jy
            for wi in range(n_words):
                if axis == 0:
                    d = bits[kz, jy, wi] ^ _shift1(bits, kz, jy, wi, n_words)
                    if wi == n_words - 1:
                        d &= last
                else:  # zero on the last row / slab (jo == jy, ko == kz there)
                    d = bits[kz, jy, wi] ^ bits[ko, jo, wi]
                while d:
                    b = _ctz(d)
                    d &= d - _ONE
                    _vertex(v, level, t_min, axis, wi * 64 + b - pad, y, z, m, n, out_v, out_n, idx,
                            pad != 0)
                    idx += 1


# ---------------------------------------------------------------------------------------------
# pass 3b: triangles
# ---------------------------------------------------------------------------------------------
@_parallel
def emit_triangles(bits, nx_virtual, tri_count, tri_edges, n_xe, n_ye, n_ze, n_tri, slab_vstart,
                   slab_tstart, out_f):
    """Pass 3b: the triangles of every active cell; slab kz starts at ``slab_tstart[kz]``.

    The vertex on edge e of a cell is the first vertex of its grid row's x-, y- or z-block plus
    the number of crossed edges of that block to its left (popcounts). ``tri_edges`` (256, 15)
    uint8 lists each case's triangles as edge triples (already reversed when the affine flips),
    padded with a valid edge number (0): every cell writes all 15 entries when its slab has
    room (no data-dependent loop exit per cell); the next cell overwrites the excess.
    """
    for kz in prange(bits.shape[0] - 1):
        _triangles_slab(bits, nx_virtual, tri_count, tri_edges, n_xe, n_ye, n_ze, n_tri,
                        slab_vstart[kz], slab_vstart[kz + 1], slab_tstart[kz], slab_tstart[kz + 1],
                        out_f, np.int64(kz))


@_inline
def _write_triangles(flat, out, end, ids, tri_edges, c, nk):
    """Write case ``c``'s ``nk`` corner entries (vertex ids of its edges) at ``flat[out:]``;
    returns the next position. With room for the largest case (15) a fixed, unrolled copy; the
    slab's last cells write exactly ``nk`` (the next slab's entries are not ours)."""
    uc = np.uint64(c)  # unsigned indices: no negative-index wrap-around code
    if out + 15 <= end:
        for k in range(15):
            flat[np.uint64(out + k)] = ids[np.uint64(tri_edges[uc, np.uint64(k)])]
    else:
        for k in range(nk):
            flat[np.uint64(out + k)] = ids[np.uint64(tri_edges[uc, np.uint64(k)])]
    return out + nk


@_serial
def _triangles_slab(bits, nx_virtual, tri_count, tri_edges, n_xe, n_ye, n_ze, n_tri, row0, row1,
                    out, out_end, out_f, kz):
    """row0 / row1: first vertex of the current grid row in slab kz / kz + 1 (advanced per row);
    the slab's triangles are out .. out_end - 1."""
    nzv, nyv, n_words = bits.shape
    last = _last_mask(nx_virtual, n_words)
    ids = np.empty(12, np.int32)  # vertex index on each of the 12 edges of the current cell
    flat = out_f.reshape(-1)
    out = 3 * out  # position in flat
    end = 3 * out_end
    for jy in range(nyv - 1):
        # first vertex of rows (kz, jy), (kz, jy+1), (kz+1, jy), (kz+1, jy+1)
        v00 = row0
        v10 = row0 + n_xe[kz, jy] + n_ye[kz, jy] + n_ze[kz, jy]
        v01 = row1
        v11 = row1 + n_xe[kz + 1, jy] + n_ye[kz + 1, jy] + n_ze[kz + 1, jy]
        row0, row1 = v10, v11
        if n_tri[kz, jy] == 0:
            continue
        # running index of the next vertex of each edge block at the start of the current word
        x00, x10, x01, x11 = v00, v10, v01, v11
        y0 = v00 + n_xe[kz, jy]
        y1 = v01 + n_xe[kz + 1, jy]
        z0 = v00 + n_xe[kz, jy] + n_ye[kz, jy]
        z1 = v10 + n_xe[kz, jy + 1] + n_ye[kz, jy + 1]
        for wi in range(n_words):
            r00, r10 = bits[kz, jy, wi], bits[kz, jy + 1, wi]
            r01, r11 = bits[kz + 1, jy, wi], bits[kz + 1, jy + 1, wi]
            s00 = _shift1(bits, kz, jy, wi, n_words)
            s10 = _shift1(bits, kz, jy + 1, wi, n_words)
            s01 = _shift1(bits, kz + 1, jy, wi, n_words)
            s11 = _shift1(bits, kz + 1, jy + 1, wi, n_words)
            any_set = r00 | s00 | r10 | s10 | r01 | s01 | r11 | s11
            all_set = r00 & s00 & r10 & s10 & r01 & s01 & r11 & s11
            active = any_set & ~all_set
            xd00, xd10, xd01, xd11 = r00 ^ s00, r10 ^ s10, r01 ^ s01, r11 ^ s11
            yd0, yd1 = r00 ^ r10, r01 ^ r11
            zd0, zd1 = r00 ^ r01, r10 ^ r11
            if wi == n_words - 1:
                active &= last
                xd00 &= last
                xd10 &= last
                xd01 &= last
                xd11 &= last
            while active:
                b = _ctz(active)
                active &= active - _ONE
                c = _case(r00, s00, r10, s10, r01, s01, r11, s11, b)
                low = _low_mask(b)
                ids[0] = x00 + _pc(xd00 & low)
                ids[1] = x10 + _pc(xd10 & low)
                ids[2] = x01 + _pc(xd01 & low)
                ids[3] = x11 + _pc(xd11 & low)
                a0 = y0 + _pc(yd0 & low)
                a1 = y1 + _pc(yd1 & low)
                ids[4] = a0
                ids[5] = a0 + _bit(yd0, b)
                ids[6] = a1
                ids[7] = a1 + _bit(yd1, b)
                a0 = z0 + _pc(zd0 & low)
                a1 = z1 + _pc(zd1 & low)
                ids[8] = a0
                ids[9] = a0 + _bit(zd0, b)
                ids[10] = a1
                ids[11] = a1 + _bit(zd1, b)
                out = _write_triangles(flat, out, end, ids, tri_edges, c, 3 * tri_count[c])
            x00 += _pc(xd00)
            x10 += _pc(xd10)
            x01 += _pc(xd01)
            x11 += _pc(xd11)
            y0 += _pc(yd0)
            y1 += _pc(yd1)
            z0 += _pc(zd0)
            z1 += _pc(zd1)
