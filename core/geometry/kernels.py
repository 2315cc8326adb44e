"""Small numba helpers shared by kernel modules."""
from numba import njit


@njit(cache=True)
def lower_bound(a, x):
    """First index of sorted ``a`` whose value is >= x (``np.searchsorted``, side="left")."""
    lo = 0
    hi = a.shape[0]
    while lo < hi:
        mid = (lo + hi) >> 1
        if a[mid] < x:
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(cache=True)
def other_corners(faces, f, i):
    """The corners ``(j, k)`` of face ``f`` after its corner ``i``, in winding order, so the
    face reads (i, j, k)."""
    if faces[f, 0] == i:
        return faces[f, 1], faces[f, 2]
    if faces[f, 1] == i:
        return faces[f, 2], faces[f, 0]
    return faces[f, 0], faces[f, 1]
