"""An independent implementation of the lblight solver contract (docs/model.md secs. 1-4), written from
that document alone with NumPy, in float64. Used by check_bake.py to verify `lblight bake`
outputs read back through OpenVDB's own Python module."""
import numpy as np

# docs/model.md sec. 1: D3Q19 order
C = np.array([
    (0, 0, 0), (1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1),
    (1, 1, 0), (-1, -1, 0), (1, -1, 0), (-1, 1, 0), (1, 0, 1), (-1, 0, -1),
    (1, 0, -1), (-1, 0, 1), (0, 1, 1), (0, -1, -1), (0, 1, -1), (0, -1, 1)], dtype=np.int64)
W = np.array([0.0] + [1 / 12] * 6 + [1 / 24] * 12)


def phase(g, i, j):
    """Discrete Henyey-Greenstein p_ij ([Geist2010] eq. 9) with the |g| = 1 limit (docs/model.md sec. 2)."""
    ni = C[i] / np.linalg.norm(C[i])
    nj = C[j] / np.linalg.norm(C[j])
    cos = float(np.dot(ni, nj))
    if g >= 1.0:
        return 1.0 if np.allclose(ni, nj) else 0.0
    if g <= -1.0:
        return 1.0 if np.allclose(ni, -nj) else 0.0
    return (1 - g * g) / (1 - 2 * g * cos + g * g) ** 1.5


def omega(sigma_a, sigma_s, g):
    """Collision matrix of [Geist2010] eqs. (5)-(8)."""
    sigma_t = sigma_a + sigma_s
    om = np.zeros((19, 19))
    om[0, 0] = -1.0
    om[0, 1:] = sigma_a
    p = np.array([[phase(g, i, j) for j in range(1, 19)] for i in range(1, 19)])
    norm = (2 * p[:6, :].sum(axis=0) + p[6:, :].sum(axis=0)) / 24  # denominator of eq. (8), per j
    pn = p / norm
    for i in range(1, 19):
        om[i, 0] = W[i]
        for j in range(1, 19):
            om[i, j] = W[i] * sigma_s * pn[i - 1, j - 1] - (sigma_t if i == j else 0.0)
    return om


def solve(density, material, omegas, absorbs, boundary, steps):
    """density, material: arrays [z, y, x] over the whole lattice (boundary layer included);
    omegas/absorbs: per material index; boundary: 19 fixed values. Returns totals [z, y, x]."""
    nz, ny, nx = density.shape
    f = np.zeros((19, nz, ny, nx))
    bmask = np.zeros((nz, ny, nx), dtype=bool)
    bmask[0, :, :] = bmask[-1, :, :] = bmask[:, 0, :] = bmask[:, -1, :] = bmask[:, :, 0] = bmask[:, :, -1] = True
    for m in range(19):
        f[m][bmask] = boundary[m]
    for _ in range(steps):
        ft = f.copy()
        for k, absorb in enumerate(absorbs):
            if absorb:
                ft[0][material == k] = 0.0
        post = ft.copy()
        for k, om in enumerate(omegas):
            sel = material == k
            post[:, sel] += density[sel] * (om @ ft[:, sel])
        new = f.copy()  # boundary nodes keep their values
        for m in range(19):
            cx, cy, cz = C[m]
            # interior target q receives post_m from q - c_m (always inside the lattice)
            new[m, 1:-1, 1:-1, 1:-1] = post[m, 1 - cz:nz - 1 - cz, 1 - cy:ny - 1 - cy, 1 - cx:nx - 1 - cx]
        f = new
    return f.sum(axis=0)


def base_boundary(j):
    b = np.zeros(19)
    if j == 0:
        b[:] = 1.0
    else:
        b[j] = 1.0
    return b
