"""Numba kernel of :mod:`anatomesh.core.export.snapshot`: z-buffered triangle rasterisation with
flat Lambert shading (both sides lit). Private: call :func:`~.snapshot.render`."""
import math

from numba import njit


@njit(cache=True)
def _shade(p0, p1, p2, light):
    """|cos| between the face normal (screen axes, y down flipped back) and the light, in [0, 1]."""
    ax, ay, az = p1[0] - p0[0], -(p1[1] - p0[1]), p1[2] - p0[2]
    bx, by, bz = p2[0] - p0[0], -(p2[1] - p0[1]), p2[2] - p0[2]
    nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    ln = math.sqrt(nx * nx + ny * ny + nz * nz)
    if ln == 0.0:
        return 0.0
    return abs(nx * light[0] + ny * light[1] + nz * light[2]) / ln


@njit(cache=True)
def rasterise(px, faces, colours, light, depth, image):
    """Draw every triangle: ``px`` (N, 3) pixel x, pixel y (down), depth (larger is nearer);
    ``faces`` (M, 3); ``colours`` (M, 3) in [0, 1]; ``depth`` (H, W) and ``image`` (H, W, 3)
    updated in place (nearest surface wins)."""
    h, w = depth.shape
    for f in range(faces.shape[0]):
        p0, p1, p2 = px[faces[f, 0]], px[faces[f, 1]], px[faces[f, 2]]
        area = (p1[0] - p0[0]) * (p2[1] - p0[1]) - (p1[1] - p0[1]) * (p2[0] - p0[0])
        if area == 0.0:
            continue
        s = 0.25 + 0.75 * _shade(p0, p1, p2, light)
        x0 = max(int(math.floor(min(p0[0], p1[0], p2[0]))), 0)
        x1 = min(int(math.ceil(max(p0[0], p1[0], p2[0]))), w - 1)
        y0 = max(int(math.floor(min(p0[1], p1[1], p2[1]))), 0)
        y1 = min(int(math.ceil(max(p0[1], p1[1], p2[1]))), h - 1)
        for y in range(y0, y1 + 1):
            cy = y + 0.5
            for x in range(x0, x1 + 1):
                cx = x + 0.5
                w0 = ((p1[0] - cx) * (p2[1] - cy) - (p1[1] - cy) * (p2[0] - cx)) / area
                w1 = ((p2[0] - cx) * (p0[1] - cy) - (p2[1] - cy) * (p0[0] - cx)) / area
                w2 = 1.0 - w0 - w1
                if w0 < 0.0 or w1 < 0.0 or w2 < 0.0:
                    continue
                z = w0 * p0[2] + w1 * p1[2] + w2 * p2[2]
                if z > depth[y, x]:
                    depth[y, x] = z
                    for c in range(3):
                        image[y, x, c] = colours[f, c] * s
