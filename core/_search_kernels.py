"""Small numba search helpers shared by kernel modules."""
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
