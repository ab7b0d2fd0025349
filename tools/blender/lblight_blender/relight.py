"""Relighting weights of lblight's base solutions for a sun (docs/output-format.md, 32-face
decomposition; the same rule as `lblight sun-weights`), in plain Python so it runs inside Blender
and is tested against the lblight binary. No bpy here."""
import math

# D3Q19 lattice directions in lblight's order: B00 is the rest direction (the ambient solution),
# Bjj the light travelling along DIRECTIONS[j] (lblight/lattice/d3q19.h).
DIRECTIONS = [
    (0, 0, 0),
    (1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1),
    (1, 1, 0), (-1, -1, 0), (1, -1, 0), (-1, 1, 0),
    (1, 0, 1), (-1, 0, -1), (1, 0, -1), (-1, 0, 1),
    (0, 1, 1), (0, -1, -1), (0, 1, -1), (0, -1, 1),
]
NEGLIGIBLE = 1e-12  # kNegligibleSunWeight: a rounding remainder asks for no base solution


def grid_name(j):
    return "B%02d" % j


def _unit(v):
    n = math.sqrt(sum(c * c for c in v))
    return tuple(c / n for c in v)


def _sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def _dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _faces():
    """The 32 triangles of the hull of the 18 unit directions, as lblight builds them."""
    unit = [None] + [_unit(d) for d in DIRECTIONS[1:]]
    faces = []
    for a in range(1, 19):
        for b in range(a + 1, 19):
            for c in range(b + 1, 19):
                pa, pb, pc = unit[a], unit[b], unit[c]
                n = _cross(_sub(pb, pa), _sub(pc, pa))
                if _dot(n, n) < 1e-12:
                    continue
                if _dot(n, pa) < 0:
                    n = tuple(-x for x in n)
                d = _dot(n, pa)
                if d <= 1e-12:
                    continue
                if any(_dot(n, unit[o]) >= d - 1e-12 for o in range(1, 19) if o not in (a, b, c)):
                    continue
                if _dot(_cross(_sub(pb, pa), _sub(pc, pa)), pa) < 0:
                    faces.append((a, c, b))
                else:
                    faces.append((a, b, c))
    assert len(faces) == 32, len(faces)
    return faces


FACES = _faces()
_UNIT = [None] + [_unit(d) for d in DIRECTIONS[1:]]


def _face_rows(f):
    """Rows of the inverse of the face's direction matrix: (alpha, beta, gamma) = rows . travel."""
    a, b, c = (_UNIT[k] for k in f)
    det = _dot(a, _cross(b, c))
    return tuple(tuple(x / det for x in r) for r in (_cross(b, c), _cross(c, a), _cross(a, b)))


_FACE_ROWS = [(f, _face_rows(f)) for f in FACES]  # once: a forest's handler decomposes per instance


def decompose(travel, negligible=NEGLIGIBLE):
    """The three directions around `travel` and their barycentric weights (sum 1)."""
    best, best_min = None, -1e300
    tx, ty, tz = travel
    for f, (r0, r1, r2) in _FACE_ROWS:
        alpha = r0[0] * tx + r0[1] * ty + r0[2] * tz
        beta = r1[0] * tx + r1[1] * ty + r1[2] * tz
        gamma = r2[0] * tx + r2[1] * ty + r2[2] * tz
        if alpha + beta + gamma <= 0:
            continue  # the face opposite the direction
        lo = min(alpha, beta, gamma)
        if lo > best_min + 1e-15:
            best_min = lo
            s = alpha + beta + gamma
            best = (f, [max(0.0, alpha / s), max(0.0, beta / s), max(0.0, gamma / s)])
    f, w = best
    w = [x if x >= negligible else 0.0 for x in w]
    s = sum(w)
    return f, [x / s for x in w]


def _sincos_deg(deg):
    """sin and cos of an angle in degrees, exact at multiples of 90 (as lblight's)."""
    q = deg / 90.0
    if q == round(q):
        return [(0.0, 1.0), (1.0, 0.0), (0.0, -1.0), (-1.0, 0.0)][int(round(q)) % 4]
    r = math.radians(deg)
    return math.sin(r), math.cos(r)


def toward_sun_from_angles(elevation_deg, azimuth_deg):
    se, ce = _sincos_deg(elevation_deg)
    sa, ca = _sincos_deg(azimuth_deg)
    return (ce * ca, ce * sa, se)


def weights(toward_sun, intensity=1.0, ambient=0.0, sky=0.0, negligible=NEGLIGIBLE):
    """{grid name: weight} for a sun (a vector toward it), an ambient level (x B00) and a sky level
    (S on the 5 downward directions, S/2 on the 8 level ones), as `lblight relight` combines them.
    `negligible`: sun weights below it are rounding (a Blender lamp's float32 matrix leaves ~1e-7
    on a third direction for a sun exactly between two) and are dropped."""
    t = _unit(toward_sun)
    out = {}
    if intensity != 0.0:
        f, w = decompose(tuple(-x for x in t), negligible)
        for j, x in zip(f, w):
            if x > negligible:
                out[grid_name(j)] = out.get(grid_name(j), 0.0) + intensity * x
    if ambient != 0.0:
        out["B00"] = out.get("B00", 0.0) + ambient
    if sky != 0.0:
        for j in range(1, 19):
            cz = DIRECTIONS[j][2]
            if cz <= 0:
                out[grid_name(j)] = out.get(grid_name(j), 0.0) + (sky if cz < 0 else 0.5 * sky)
    return out


# The grids a sun at or above an object's horizon, its ambient and its sky can ever select: B00 and
# the 13 level-or-downward directions (a sun above the horizon travels downward, and the 32 faces
# split along the horizon's octagon, so its three directions are level or downward; the sky uses
# the same 13). A material binding these serves every sun and every rotation about the vertical:
# 14 light grids + density + brown = 16, EEVEE's limit on a material's grids (docs/blender.md).
HEMISPHERE = [grid_name(j) for j in range(19) if DIRECTIONS[j][2] <= 0]


def frame_weights(toward_sun, intensity=1.0, ambient=0.0, sky=0.0, negligible=NEGLIGIBLE):
    """weights() for a sun given in an object's own frame: a sun below that frame's horizon
    (toward_sun z < 0) lights nothing directly, only the ambient and the sky terms remain."""
    if _dot(toward_sun, toward_sun) == 0.0 or toward_sun[2] < 0.0:
        intensity = 0.0
        toward_sun = (0.0, 0.0, 1.0)
    return weights(toward_sun, intensity, ambient, sky, negligible)
