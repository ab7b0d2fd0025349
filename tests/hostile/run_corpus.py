#!/usr/bin/env python3
"""Hostile-input corpus for lblight: generates every case, runs it, checks the outcome.

Usage: run_corpus.py LBLIGHT_EXE SOURCE_DIR [--only NAME_SUBSTRING] [--list] [--keep DIR]
                     [--timeout SECONDS] [--class CLASS]

Every case is written into its own fresh folder (under a temporary folder in /tmp, or under
--keep DIR, which is then left in place), and lblight runs there as the working directory with a
timeout (the whole process group is killed: HANG) and an address-space limit of 4 GiB (a blow-up
fails fast instead of meeting the OOM killer). A case passes when
  - the process ended by itself (no HANG) and not by a signal (no CRASH),
  - the exit code is the expected one (or one of the expected ones),
  - stdout + stderr contain every expected fragment (case-insensitive; a tuple is "any of"),
  - no forbidden pattern appears (raw library messages, negative sizes, leaked file contents),
  - nothing the case forbids is left in its folder (an output directory, a hidden staging folder
    `.*.staging-*`, a temporary `*.tmp-*` file), everything it requires is there, the files it
    protects are byte for byte unchanged, and its own check (if any) agrees.
Standard library only; pyopenvdb (Debian python3-openvdb, /usr/bin/python3) is used when it can
be imported to craft .vdb files, and the cases that need it are skipped with a note otherwise.
Exit status: 0 when every case that ran passed, 1 when any failed, 2 for a usage error.
See tests/hostile/README.md for the classes and how to add a case.
"""

import argparse
import fnmatch
import json
import os
import random
import re
import resource
import shutil
import signal
import stat
import struct
import subprocess
import sys
import tempfile
import threading
import time
import zlib

SYSTEM_PYTHON = "/usr/bin/python3"
if __name__ == "__main__":
    try:
        import pyopenvdb as vdb  # noqa: F401
    except Exception:  # not importable by this interpreter: the system one may have it
        vdb = None
        if (os.path.realpath(sys.executable) != os.path.realpath(SYSTEM_PYTHON) and os.path.exists(SYSTEM_PYTHON)
                and not os.environ.get("LBLIGHT_HOSTILE_NO_REEXEC")):
            probe = subprocess.run([SYSTEM_PYTHON, "-c", "import pyopenvdb"], stdout=subprocess.DEVNULL,
                                   stderr=subprocess.DEVNULL)
            if probe.returncode == 0:
                os.environ["LBLIGHT_HOSTILE_NO_REEXEC"] = "1"
                os.execv(SYSTEM_PYTHON, [SYSTEM_PYTHON, os.path.abspath(__file__)] + sys.argv[1:])
else:
    try:
        import pyopenvdb as vdb  # noqa: F401
    except Exception:
        vdb = None

GiB = 1 << 30
MEMORY_LIMIT = 4 * GiB
FILE_SIZE_LIMIT = 4 * GiB          # a runaway writer is stopped (SIGXFSZ) before it fills the disk
DEFAULT_TIMEOUT = 60.0
CLASSES = ("crash", "hang", "memory", "partial-output", "wrong-ok", "trust", "message", "injection", "overwrite")

INT32_MAX = 2**31 - 1
INT32_MIN = -2**31

# Left by an interrupted or failed run (lblight/io/output_dir.cpp names): never allowed unless a case says so.
DEFAULT_MUST_NOT_EXIST = ["*.staging-*", "*.tmp-*"]

# Never shown to a user, in any case: raw library exception texts, aborts, negative sizes, ANSI
# colour codes of OpenVDB's logger on a non-terminal.
DEFAULT_FORBID = [
    r"json\.exception", r"\[json\.", r"type_error\.\d", r"parse_error\.\d", r"out_of_range\.\d",
    r"terminate called", r"std::bad_alloc", r"std::length_error", r"std::out_of_range", r"basic_string",
    r"vector::_M", r"what\(\):", r"Assertion .* failed", r"\x1b\[",
    r"[\x00-\x08\x0b\x0c\x0e-\x1a\x1c-\x1f\x7f]",  # raw control bytes (echoed binary input)
    r"(?<![\w.\-+])-\d+x-?\d+x-?\d+",          # "spans -1295x1x1 voxels"
]
PASSWD_LEAK = r"root:[^:\n]*:0:0:"              # /etc/passwd content echoed back


class SetupError(Exception):
    pass


class SkipCase(Exception):
    pass


# ----------------------------------------------------------------------------------------------
# Child process limits

# The limits are set by a tiny launcher that then execs lblight (same PID, same process group),
# not by preexec_fn, which is unsafe while other threads run (--jobs, the pipe readers).
_LAUNCHER = r"""
import json, os, resource, sys
a = json.loads(sys.argv[1])
resource.setrlimit(resource.RLIMIT_AS, (a["as"], a["as"]))
resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
resource.setrlimit(resource.RLIMIT_FSIZE, (a["fsize"], a["fsize"]))
if a["nobody"]:
    os.setgroups([])
    os.setgid(65534)
    os.setuid(65534)
os.execv(a["argv"][0], a["argv"])
"""


def limited(cmd, run_as_nobody=False):
    """cmd wrapped so that it runs under the corpus' limits (RLIMIT_AS 4 GiB, no core, file size)."""
    spec = {"as": MEMORY_LIMIT, "fsize": FILE_SIZE_LIMIT, "nobody": bool(run_as_nobody), "argv": list(cmd)}
    return [sys.executable, "-S", "-c", _LAUNCHER, json.dumps(spec)]


def child_env():
    env = dict(os.environ)
    env["OMP_WAIT_POLICY"] = "PASSIVE"   # as tests/CMakeLists.txt: side-by-side OpenMP runs
    env.pop("LBLIGHT_HOSTILE_NO_REEXEC", None)
    return env


# ----------------------------------------------------------------------------------------------
# Helpers for writing inputs

def box_model(name="m", res=8, scale=0.5, material="cloud", **extra):
    m = {"name": name,
         "density": {"type": "procedural", "shape": "box", "resolution": res, "density_scale": scale},
         "material": material}
    m.update(extra)
    return m


def vdb_model(path="d.vdb", name="m", material="cloud", **density_extra):
    d = {"type": "vdb", "path": path}
    d.update(density_extra)
    return {"name": name, "density": d, "material": material}


def mesh_model(path="m.obj", name="m", resolution=8, material="cloud", **density_extra):
    d = {"type": "mesh", "path": path, "resolution": resolution}
    d.update(density_extra)
    return {"name": name, "density": d, "material": material}


def scene_obj(models=None, lighting=None, solver=None, **extra):
    s = {"version": 1,
         "models": models if models is not None else [box_model()],
         "lighting": lighting if lighting is not None else {"mode": "base", "solutions": "0,6"},
         "solver": solver if solver is not None else {"iterations": 4}}
    s.update(extra)
    return s


TRIANGLE_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
TETRA_OBJ = ("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n"
             "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")


def sphere_soup_obj(n_lat=120, n_lon=240):
    """A closed UV sphere of 2 * n_lat * n_lon triangles: enough work to interrupt a voxelisation."""
    import math
    lines = ["o leaves_sphere"]
    for i in range(n_lat + 1):
        th = math.pi * i / n_lat
        for j in range(n_lon):
            ph = 2 * math.pi * j / n_lon
            lines.append("v %.6f %.6f %.6f" % (math.sin(th) * math.cos(ph), math.sin(th) * math.sin(ph), math.cos(th)))
    for i in range(n_lat):
        for j in range(n_lon):
            a = i * n_lon + j + 1
            b = i * n_lon + (j + 1) % n_lon + 1
            c = a + n_lon
            d = b + n_lon
            lines.append("f %d %d %d" % (a, b, d))
            lines.append("f %d %d %d" % (a, d, c))
    return "\n".join(lines) + "\n"


class Ctx:
    """What a case's setup and check functions get: the case folder and helpers to fill it."""

    def __init__(self, runner, folder):
        self.runner = runner
        self.exe = runner.exe
        self.src = runner.src
        self.dir = folder
        self.vdb = vdb
        self.notes = []

    # paths and plain files
    def p(self, rel):
        return os.path.join(self.dir, rel)

    def mkdir(self, rel):
        os.makedirs(self.p(rel), exist_ok=True)
        return self.p(rel)

    def write(self, rel, data):
        path = self.p(rel)
        os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
        with open(path, "wb" if isinstance(data, (bytes, bytearray)) else "w") as f:
            f.write(data)
        return path

    def read(self, rel):
        with open(self.p(rel), "rb") as f:
            return f.read()

    def json(self, rel, obj):
        return self.write(rel, json.dumps(obj, indent=1))

    def load_json(self, rel):
        with open(self.p(rel)) as f:
            return json.load(f)

    def scene(self, rel="scene.json", **kw):
        return self.json(rel, scene_obj(**kw))

    def fifo(self, rel):
        path = self.p(rel)
        os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
        os.mkfifo(path)
        return path

    def symlink(self, target, rel):
        path = self.p(rel)
        os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
        if os.path.lexists(path):
            os.remove(path)
        os.symlink(target, path)
        return path

    def sparse(self, rel, size):
        with open(self.p(rel), "wb") as f:
            f.truncate(size)
        return self.p(rel)

    def need_vdb(self):
        if self.vdb is None:
            raise SkipCase("pyopenvdb not available (Debian python3-openvdb)")

    # running lblight during setup (same limits, no timeout games)
    def lblight(self, args, cwd=None, timeout=120):
        p = subprocess.run(limited([self.exe] + list(args)), cwd=cwd or self.dir, stdin=subprocess.DEVNULL,
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=child_env(), timeout=timeout)
        if p.returncode != 0:
            tail = (p.stderr or b"").decode("utf-8", "replace").strip().splitlines()[-1:] or [""]
            raise SetupError("setup command 'lblight %s' exited %d: %s" % (" ".join(args), p.returncode, tail[0]))
        return p

    # shared products, made once per corpus run and copied into the case
    def bake(self, rel="ref"):
        """A small valid bake (box, resolution 8, B00 and B06, 4 steps) copied to rel."""
        src = self.runner.cached_bake()
        shutil.copytree(src, self.p(rel), symlinks=True)
        return self.p(rel)

    def small_vdb(self, rel="d.vdb"):
        """A bake's m.vdb: grids density (float), B00 and B06 (Vec3f)."""
        shutil.copyfile(os.path.join(self.runner.cached_bake(), "m.vdb"), self.p(rel))
        return self.p(rel)

    def small_lbh(self, rel="m.lbh"):
        shutil.copyfile(self.runner.cached_lbh(), self.p(rel))
        return self.p(rel)

    def edit_manifest(self, outdir, fn):
        m = self.load_json(os.path.join(outdir, "manifest.json"))
        fn(m)
        self.json(os.path.join(outdir, "manifest.json"), m)

    # pyopenvdb crafting
    def float_grid(self, voxels, name="density", background=0.0, voxel_size=0.1, transform=None, value=0.5):
        self.need_vdb()
        g = self.vdb.FloatGrid(background=background)
        g.name = name
        a = g.getAccessor()
        for v in voxels:
            if len(v) == 4:
                a.setValueOn(tuple(v[:3]), v[3])
            else:
                a.setValueOn(tuple(v), value)
        g.transform = transform if transform is not None else self.vdb.createLinearTransform(voxelSize=voxel_size)
        return g

    def vec3_grid(self, voxels, name="B00", voxel_size=0.1, value=(1.0, 2.0, 3.0), metadata=None):
        self.need_vdb()
        g = self.vdb.Vec3SGrid()
        g.name = name
        a = g.getAccessor()
        for v in voxels:
            if len(v) == 4:
                a.setValueOn(tuple(v[:3]), tuple(v[3]))
            else:
                a.setValueOn(tuple(v), value)
        g.transform = self.vdb.createLinearTransform(voxelSize=voxel_size)
        if metadata:
            for k, val in metadata.items():
                g[k] = val
        return g

    def write_vdb(self, rel, grids, metadata=None):
        self.need_vdb()
        if metadata:
            self.vdb.write(self.p(rel), grids=grids, metadata=metadata)
        else:
            self.vdb.write(self.p(rel), grids=grids)
        return self.p(rel)

    def edit_vdb(self, rel, fn):
        """fn(list of grids) -> list of grids; file metadata kept."""
        self.need_vdb()
        grids, meta = self.vdb.readAll(self.p(rel))
        grids = fn(list(grids))
        self.vdb.write(self.p(rel), grids=grids, metadata=meta)

    def dead_pid(self):
        p = subprocess.Popen(["true"])
        p.wait()
        return p.pid


def box_voxels(x0, y0, z0, n=2):
    return [(x0 + i, y0 + j, z0 + k) for i in range(n) for j in range(n) for k in range(n)]


def set_voxel(grid, ijk, value):
    grid.getAccessor().setValueOn(ijk, value)
    return grid


def replace_grid(name, make):
    def fn(grids):
        out = []
        for g in grids:
            out.append(make(g) if g.name == name else g)
        return out
    return fn


# ----------------------------------------------------------------------------------------------
# .vdb file structure (enough to aim damage at the header and grid descriptors)

def vdb_layout(data):
    """Offsets in an OpenVDB file: header fields, file metadata, grid descriptors."""
    o = 0
    lay = {"magic": 0, "version": 8, "lib_major": 12, "lib_minor": 16, "has_offsets": 20, "uuid": 21}
    o = 57
    lay["meta_count"] = o
    (count,) = struct.unpack_from("<i", data, o)
    o += 4

    def string():
        nonlocal o
        (n,) = struct.unpack_from("<I", data, o)
        at = o
        o += 4 + n
        return at, data[at + 4:at + 4 + n]

    lay["meta"] = []
    for _ in range(count):
        k = string()
        t = string()
        v = string()
        lay["meta"].append((k, t, v))
    lay["grid_count"] = o
    (gc,) = struct.unpack_from("<i", data, o)
    o += 4
    lay["grids"] = []
    for _ in range(gc):
        name = string()
        gtype = string()
        parent = string()
        pos = o
        gp, bp, ep = struct.unpack_from("<qqq", data, o)
        lay["grids"].append({"name_at": name[0], "name": name[1], "type_at": gtype[0], "type": gtype[1],
                             "pos_at": pos, "grid_pos": gp, "block_pos": bp, "end_pos": ep})
        o = ep
    return lay


def patch(data, offset, fmt, *values):
    b = bytearray(data)
    struct.pack_into(fmt, b, offset, *values)
    return bytes(b)


def damaged_vdb(ctx, rel, how):
    """A bake's m.vdb damaged as `how` says, written to rel."""
    with open(os.path.join(ctx.runner.cached_bake(), "m.vdb"), "rb") as f:
        data = f.read()
    lay = vdb_layout(data)
    g0 = lay["grids"][0]
    if how == "empty":
        data = b""
    elif how.startswith("cut-"):
        where = how[4:]
        n = {"magic": 6, "header": 40, "meta": lay["grid_count"] - 3, "descriptor": g0["pos_at"] + 5,
             "grid-data": (g0["grid_pos"] + g0["end_pos"]) // 2, "last-byte": len(data) - 1,
             "half": len(data) // 2}[where]
        data = data[:n]
    elif how == "bad-magic":
        data = patch(data, 0, "<q", 0x1234567)
    elif how == "future-version":
        data = patch(data, 8, "<I", 99999)
    elif how == "grid-count-huge":
        data = patch(data, lay["grid_count"], "<i", INT32_MAX)
    elif how == "grid-count-negative":
        data = patch(data, lay["grid_count"], "<i", -5)
    elif how == "meta-count-huge":
        data = patch(data, lay["meta_count"], "<i", INT32_MAX)
    elif how == "name-length-huge":
        data = patch(data, g0["name_at"], "<I", 0xFFFFFFF0)
    elif how == "type-unknown":
        # keep the length, garble the type name: "Tree_float_5_4_3" -> "Tree_xxxxx_5_4_3"
        at = g0["type_at"] + 4 + 5
        b = bytearray(data)
        b[at:at + 5] = b"xxxxx"
        data = bytes(b)
    elif how == "end-pos-huge":
        data = patch(data, g0["pos_at"] + 16, "<q", 1 << 62)
    elif how == "grid-pos-negative":
        data = patch(data, g0["pos_at"], "<q", -1000)
    elif how == "block-pos-past-end":
        data = patch(data, g0["pos_at"] + 8, "<q", len(data) + 4096)
    elif how == "zeroed-grid-data":
        b = bytearray(data)
        start = g0["grid_pos"] + 16
        b[start:start + 256] = bytes(256)
        data = bytes(b)
    elif how == "random-grid-data":
        rng = random.Random(1234)
        b = bytearray(data)
        start = (g0["grid_pos"] + g0["end_pos"]) // 2
        for i in range(start, min(start + 512, g0["end_pos"])):
            b[i] = rng.randrange(256)
        data = bytes(b)
    else:
        raise ValueError(how)
    return ctx.write(rel, data)


# ----------------------------------------------------------------------------------------------
# .lbh file structure (docs/lbh-format.md sec. 2)

def lbh_fix_crcs(data):
    b = bytearray(data)
    (count,) = struct.unpack_from("<I", b, 32)
    if 256 + 128 * count <= len(b):
        struct.pack_into("<I", b, 216, zlib.crc32(bytes(b[256:256 + 128 * count])) & 0xFFFFFFFF)
    struct.pack_into("<I", b, 252, zlib.crc32(bytes(b[0:252])) & 0xFFFFFFFF)
    return bytes(b)


def lbh_variant(ctx, rel, how):
    with open(ctx.runner.cached_lbh(), "rb") as f:
        data = f.read()
    fix = True
    if how == "truncated-1":
        data, fix = data[:-1], False
    elif how == "truncated-header":
        data, fix = data[:100], False
    elif how == "bad-header-crc":
        data, fix = patch(data, 252, "<I", 0xDEADBEEF), False
    elif how == "bad-section-crc":
        b = bytearray(data)
        b[-1] ^= 0x55
        data, fix = bytes(b), False
    elif how == "big-endian":
        data = patch(data, 12, ">I", 0x01020304)
    elif how == "version-3":
        data = patch(data, 8, "<I", 3)
    elif how == "dims-2p20":
        data = patch(data, 40, "<iii", 1 << 20, 1 << 20, 1 << 20)
        n = max(1, -(-((1 << 20) - 1) // 3))
        data = patch(data, 64, "<III", n, n, n)
    elif how == "file-bytes-huge":
        data = patch(data, 24, "<Q", 1 << 63)
    elif how == "solutions-4096":
        data = patch(data, 32, "<I", 4096)
    elif how == "index-min-overflow":
        data = patch(data, 52, "<iii", INT32_MAX - 2, 0, 0)
    elif how == "matrix-nan":
        data = patch(data, 80, "<d", float("nan"))
    elif how == "matrix-singular":
        data = patch(data, 80, "<ddd", 0.0, 0.0, 0.0)
    elif how == "coeff-count-huge":
        data = patch(data, 256 + 56, "<Q", 1 << 60)
    elif how == "masks-offset-past-end":
        data = patch(data, 256 + 64, "<Q", len(data) + (1 << 40))
    elif how == "direction-not-index":  # entry 0 keeps its index and points along B05
        data = patch(data, 256 + 20, "<iii", 0, 0, 1)
    elif how == "name-unterminated":
        b = bytearray(data)
        b[256:256 + 16] = b"ABCDEFGHIJKLMNOP"
        data = bytes(b)
    else:
        raise ValueError(how)
    if fix:
        data = lbh_fix_crcs(data)
    return ctx.write(rel, data)


# ----------------------------------------------------------------------------------------------
# Checks used by several cases

def check_report_iterations(steps):
    def check(ctx, res):
        if res.returncode != 0:
            return None   # refused: fine (the exit code and fragments were checked)
        try:
            rep = ctx.load_json("rep/report.json")
        except Exception as e:  # noqa: BLE001
            return "exit 0 but rep/report.json unreadable: %s" % e
        for c in rep.get("curves", []):
            pts = next((v for k, v in c.items() if k.startswith("points")), [])
            last = max((p[0] for p in pts), default=0)
            if c.get("stop_step", 0) > steps or last > steps:
                return ("--iterations %d ignored: %s %s stops at step %s (points up to %s)"
                        % (steps, c.get("solution"), c.get("run"), c.get("stop_step"), last))
        return None
    return check


def grid_active_voxels(ctx, vdb_rel, grid):
    p = subprocess.run(limited([ctx.exe, "inspect", vdb_rel, "--json"]), cwd=ctx.dir, stdout=subprocess.PIPE,
                       stderr=subprocess.DEVNULL, env=child_env(), timeout=60)
    if p.returncode != 0:
        raise SetupError("lblight inspect %s --json exited %d" % (vdb_rel, p.returncode))
    j = json.loads(p.stdout)
    for g in j.get("grids", []):
        if g.get("name") == grid:
            return g.get("active_voxels", 0)
    return 0


def check_small_triangle_kept(ctx, res):
    """The far-only mesh (same --bounds) gives fewer density voxels than both triangles together."""
    if res.returncode != 0:
        return "voxelize failed"
    both = grid_active_voxels(ctx, "v.vdb", "density")
    ctx.lblight(["voxelize", "far.obj", "-r", "64", "--bounds"] + BOUNDS_SF + ["-o", "far.vdb"])
    far = grid_active_voxels(ctx, "far.vdb", "density")
    if both <= far:
        return "the small triangle was dropped: %d density voxels with it, %d without" % (both, far)
    if ctx.vdb is not None:
        g = ctx.vdb.read(ctx.p("v.vdb"), "density")
        near = False
        vs = g.transform.voxelSize()[0]
        for it in g.citerOnValues():
            w = g.transform.indexToWorld(it.min)
            if all(abs(c) <= 2 * vs for c in w) and it.value > 0:
                near = True
        if not near:
            return "no density voxel with a value > 0 near the small triangle at the origin"
    return None


BOUNDS_SF = ["-1", "-1", "-1", "101", "101", "101"]


def check_tiny_far_triangle(ctx, res):
    if res.returncode != 0:
        return None
    n = grid_active_voxels(ctx, "v.vdb", "density")
    if n <= 0:
        return "voxelize exited 0 but the density grid is empty"
    return None


def check_same_as_bake(other_scene):
    """A bake that succeeded must equal the bake of other_scene (lblight compare, tolerance 1e-4)."""
    def check(ctx, res):
        if res.returncode != 0:
            return None
        ctx.lblight(["bake", other_scene, "-o", "expected"])
        p = subprocess.run(limited([ctx.exe, "compare", "expected", "out", "--tolerance", "1e-4"]), cwd=ctx.dir,
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=child_env(), timeout=60)
        if p.returncode != 0:
            lines = p.stdout.decode("utf-8", "replace").strip().splitlines()
            return "exit 0 but the result differs from the equivalent scene: %s" % (lines[-1] if lines else p.returncode)
        return None
    return check


def check_lossless_roundtrip(ctx, res):
    """docs/model.md sec. 7: threshold 0 is lossless up to the float rounding of the Haar filters,
    i.e. every decoded value within a few float ulps of its block's largest: at most 1e-6 of the
    grid's largest |value| (a pointwise relative comparison would count rounding on values near 0)."""
    if res.returncode != 0:
        return "compress --threshold 0 failed"
    ctx.lblight(["decompress", "ref/m.lbh", "-o", "rt.vdb"])
    if ctx.vdb is None:
        return None
    for name in ("B00", "B06"):
        a, b = ctx.vdb.read(ctx.p("ref/m.vdb"), name), ctx.vdb.read(ctx.p("rt.vdb"), name)
        peak, worst = 0.0, 0.0
        for it in a.citerOnValues():
            peak = max(peak, max(abs(c) for c in it.value))
        acc = b.getConstAccessor()
        for it in a.citerOnValues():
            got = acc.getValue(it.min)
            worst = max(worst, max(abs(x - y) for x, y in zip(it.value, got)))
        if worst > 1e-6 * peak:
            return "threshold 0 decodes %s with a max error of %.3g of its largest value (more than float rounding)" % (
                name, worst / peak if peak else worst)
    return None


def check_huge_values_roundtrip(ctx, res):
    if res.returncode != 0:
        return None
    ctx.lblight(["decompress", "big.lbh", "-o", "rt.vdb"])
    if ctx.vdb is None:
        return None
    g = ctx.vdb.read(ctx.p("rt.vdb"), "B00")
    import math
    for it in g.citerOnValues():
        if not all(math.isfinite(c) for c in it.value):
            return "compress exited 0 but decodes a non-finite value %r at %r" % (it.value, it.min)
        if abs(it.value[0] - 3e38) > 3e36:
            return "compress exited 0 but decodes %r instead of about 3e38 at %r" % (it.value, it.min)
    return None


def check_file_still(rel, what):
    def check(ctx, res):
        if not os.path.exists(ctx.p(rel)):
            return "%s (%s) was deleted" % (rel, what)
        return None
    return check


# ----------------------------------------------------------------------------------------------
# The cases

CASES = []


def case(name, cls, args, setup=None, expect_exit=2, expect=(), **kw):
    assert cls in CLASSES, cls
    assert not any(c["name"] == name for c in CASES), name
    c = {"name": name, "class": cls, "args": list(args), "setup": setup or (lambda ctx: None),
         "expect_exit": expect_exit, "expect": list(expect)}
    c.update(kw)
    CASES.append(c)
    return c


VDB_NAMED = ("d.vdb", "/models/0/density")    # a content problem of a scene's .vdb: file or pointer
NOT_REGULAR = ("regular file", "not a file", "is a pipe", "fifo", "device", "folder", "directory")
MEMORY = ("memory", "too large", "too big", "size", "exceeds")
OUT_GONE = ["out", ".out.staging-*", "*.staging-*", "*.tmp-*"]


def scene_writer(**kw):
    return lambda ctx: ctx.scene(**kw)


def raw_writer(rel, text):
    return lambda ctx: ctx.write(rel, text)


def seq(*fns):
    def run(ctx):
        for f in fns:
            f(ctx)
    return run


# ---------------------------------------------------------------------------------------- crash

def _huge_coord_scene(voxels, crop=None):
    def setup(ctx):
        ctx.write_vdb("d.vdb", [ctx.float_grid(voxels)])
        m = vdb_model()
        if crop is not None:
            m["crop"] = crop
        ctx.scene(models=[m])
    return setup


case("crash-vdb-voxel-at-int32-max-validate", "crash", ["validate", "--no-timing", "scene.json"],
     _huge_coord_scene([(INT32_MAX, 0, 0)]), 2, [VDB_NAMED, ("index", "coordinate", "range", "lattice", "margin")],
     needs_vdb=True, desc="one density voxel at x = 2^31-1: the margin node would be at 2^31")
case("crash-vdb-voxel-at-int32-max-bake", "crash", ["bake", "scene.json", "-o", "out"],
     _huge_coord_scene([(INT32_MAX, 0, 0)]), 2, [VDB_NAMED], needs_vdb=True, must_not_exist=OUT_GONE)
case("crash-vdb-voxel-below-int32-max", "crash", ["validate", "--no-timing", "scene.json"],
     _huge_coord_scene([(INT32_MAX - 1, 5, 5)]), (0, 2), [VDB_NAMED], needs_vdb=True,
     desc="voxel at 2^31-2: the lattice ends exactly at 2^31-1 (valid, or refused by name; never a crash)")
case("crash-vdb-voxel-at-int32-min-validate", "crash", ["validate", "--no-timing", "scene.json"],
     _huge_coord_scene([(INT32_MIN, 0, 0), (INT32_MIN + 1, 1, 1)]), 2, [VDB_NAMED], needs_vdb=True,
     desc="density at x = -2^31: the margin would start at -2^31-1")
case("crash-vdb-voxel-at-int32-min-nocrop-bake", "crash", ["bake", "scene.json", "-o", "out"],
     _huge_coord_scene([(INT32_MIN, INT32_MIN, INT32_MIN)], crop=False), 2, [VDB_NAMED], needs_vdb=True,
     must_not_exist=OUT_GONE)
case("crash-vdb-lattice-starts-at-int32-min", "crash", ["bake", "scene.json", "-o", "out"],
     _huge_coord_scene([(INT32_MIN + 1, 0, 0), (INT32_MIN + 2, 1, 1)]), (0, 2), [],
     needs_vdb=True, timeout=30,
     desc="density at x = -2^31+1: the lattice (margin 1) starts exactly at -2^31; bake it or refuse it cleanly")


def _compress_at(x0, meta_min=None):
    def setup(ctx):
        vox = box_voxels(x0, 0, 0, 4)
        md = None
        if meta_min is not None:
            md = {"lblight_lattice_min": (meta_min, 0, 0), "lblight_lattice_dims": (4, 4, 4), "lblight_solution": 0}
        ctx.write_vdb("b.vdb", [ctx.vec3_grid(vox, "B00", metadata=md)])
    return setup


case("crash-compress-vec3-grid-at-int32-max", "crash", ["compress", "b.vdb", "--threshold", "0"],
     _compress_at(INT32_MAX - 3, INT32_MAX - 3), (0, 2), ["b.vdb"], needs_vdb=True, timeout=30,
     desc="a 4^3 Vec3f block ending at 2^31-1: forward borders of sub-blocks would reach past it")
case("crash-inspect-vdb-at-int32-extremes", "crash", ["inspect", "d.vdb"],
     lambda ctx: ctx.write_vdb("d.vdb", [ctx.float_grid([(INT32_MIN, INT32_MIN, INT32_MIN),
                                                         (INT32_MAX, INT32_MAX, INT32_MAX)])]),
     0, ["d.vdb", "density"], needs_vdb=True)


def _compare_type_swap(maker):
    def setup(ctx):
        ctx.bake("a")
        ctx.bake("b")
        ctx.edit_vdb("b/m.vdb", replace_grid("B06", lambda g: maker(ctx, g)))
    return setup


def _as_float(ctx, g):
    f = ctx.vdb.FloatGrid()
    f.name = "B06"
    f.transform = g.transform
    f.getAccessor().setValueOn((3, 3, 3), 0.5)
    return f


def _as_bool(ctx, g):
    f = ctx.vdb.BoolGrid()
    f.name = "B06"
    f.transform = g.transform
    f.getAccessor().setValueOn((3, 3, 3), True)
    return f


case("crash-compare-other-B06-float", "crash", ["compare", "a", "b"], _compare_type_swap(_as_float), 2,
     ["B06", ("float", "vec3", "type")], needs_vdb=True,
     desc="the other bake's B06 is a float grid instead of Vec3f")
case("crash-compare-other-B06-bool", "crash", ["compare", "a", "b"], _compare_type_swap(_as_bool), 2,
     ["B06"], needs_vdb=True)
case("crash-compare-reference-B06-float", "crash", ["compare", "b", "a"], _compare_type_swap(_as_float), 2,
     ["B06"], needs_vdb=True)
case("crash-compare-other-B06-missing", "crash", ["compare", "a", "b"],
     lambda ctx: (ctx.bake("a"), ctx.bake("b"), ctx.edit_vdb("b/m.vdb", lambda gs: [g for g in gs if g.name != "B06"])),
     2, ["B06"], needs_vdb=True)

for how, frags in [("empty", []), ("cut-magic", []), ("cut-header", []), ("cut-meta", []),
                   ("cut-descriptor", []), ("cut-grid-data", ["density"]), ("cut-half", []),
                   ("cut-last-byte", ["B06"]), ("bad-magic", []), ("future-version", []),
                   ("grid-count-huge", []), ("grid-count-negative", []), ("meta-count-huge", []),
                   ("name-length-huge", []), ("type-unknown", []), ("end-pos-huge", []),
                   ("grid-pos-negative", []), ("block-pos-past-end", [])]:
    case("crash-vdb-density-%s" % how, "crash", ["validate", "--no-timing", "scene.json"],
         (lambda h: seq(lambda ctx: damaged_vdb(ctx, "d.vdb", h), scene_writer(models=[vdb_model()])))(how),
         2, ["d.vdb"] + frags, desc=".vdb density source damaged: %s" % how)

for cmd, how in [("inspect", "cut-half"), ("inspect", "name-length-huge"), ("compress", "cut-last-byte"),
                 ("compress", "grid-count-huge"), ("inspect", "zeroed-grid-data"),
                 ("compress", "random-grid-data")]:
    extra = ["--threshold", "0"] if cmd == "compress" else []
    unseen = how == "random-grid-data"   # output-format.md: without checksums such damage may decode unseen
    case("crash-%s-vdb-%s" % (cmd, how), "crash", [cmd, "d.vdb"] + extra,
         (lambda h: lambda ctx: damaged_vdb(ctx, "d.vdb", h))(how),
         (0, 2) if unseen else 2, [("d.vdb", "d.lbh") if unseen else "d.vdb"], must_not_exist=["*.tmp-*"] if unseen else ["d.lbh", "*.tmp-*"],
         desc="%s of a damaged .vdb (%s)%s" % (cmd, how, "; docs/output-format.md admits OpenVDB may crash on "
                                               "damaged grid data" if "grid-data" in how else ""))

case("crash-compare-other-vdb-truncated", "crash", ["compare", "a", "b"],
     lambda ctx: (ctx.bake("a"), ctx.bake("b"), damaged_vdb(ctx, "b/m.vdb", "cut-half")), 2, ["m.vdb"])

for nm, text, frags in [
        ("index-huge", TRIANGLE_OBJ.replace("f 1 2 3", "f 1 2 99999999999999999999"), [":4"]),
        ("index-2p63", TRIANGLE_OBJ.replace("f 1 2 3", "f 1 2 9223372036854775808"), [":4"]),
        ("index-zero", TRIANGLE_OBJ.replace("f 1 2 3", "f 0 1 2"), [":4"]),
        ("index-negative-beyond", TRIANGLE_OBJ.replace("f 1 2 3", "f -1 -2 -4"), [":4"]),
        ("index-int64-min", TRIANGLE_OBJ.replace("f 1 2 3", "f 1 2 -9223372036854775808"), [":4"]),
        ("index-texture-garbage", TRIANGLE_OBJ.replace("f 1 2 3", "f 1/x/y 2//999999999999 3/"), []),
        ("vertex-nan", TRIANGLE_OBJ.replace("v 0 0 0", "v nan 0 0"), [":1"]),
        ("vertex-inf-literal", TRIANGLE_OBJ.replace("v 1 0 0", "v 1e400 0 0"), [":2"]),
        ("vertex-hex-float", TRIANGLE_OBJ.replace("v 1 0 0", "v 0x1p2000 0 0"), [":2"]),
        ("vertex-missing-coordinate", TRIANGLE_OBJ.replace("v 1 0 0", "v 1 0"), [":2"]),
        ("face-one-vertex", "v 0 0 0\nf 1\n", [":2"]),
        ("very-long-number-line", "v " + "9" * 5_000_000 + " 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", [":1"]),
        ("binary-garbage", bytes(random.Random(7).randrange(256) for _ in range(200_000)), []),
        ("nul-bytes", b"v 0 0 0\x00\x00\nv 1 0 0\nv 0 1 0\nf 1 2\x003\n", []),
        ("coordinates-overflow-float32", "v 3e38 0 0\nv -3e38 0 0\nv 0 3e38 0\nf 1 2 3\n", []),
]:
    ok = (0, 2) if nm in ("index-texture-garbage", "coordinates-overflow-float32", "nul-bytes") else 2
    case("crash-obj-%s" % nm, "crash", ["voxelize", "m.obj", "-r", "8", "-o", "v.vdb"],
         (lambda t: lambda ctx: ctx.write("m.obj", t))(text), ok, ["m.obj"] + frags,
         must_not_exist=(["v.vdb", "*.tmp-*"] if ok == 2 else ["*.tmp-*"]), max_output_bytes=64 << 10,
         desc="voxelize an OBJ with %s" % nm)

case("crash-obj-in-scene-face-index-zero", "crash", ["bake", "scene.json", "-o", "out"],
     seq(raw_writer("m.obj", TRIANGLE_OBJ.replace("f 1 2 3", "f 0 1 2")), scene_writer(models=[mesh_model()])),
     2, ["m.obj", ":4"], must_not_exist=OUT_GONE)


def _deep_json(depth, where="comment"):
    def setup(ctx):
        s = json.dumps(scene_obj())
        s = s[:-1] + ', "%s": ' % where + "[" * depth + "]" * depth + "}"
        ctx.write("scene.json", s)
    return setup


case("crash-json-nesting-1e6", "crash", ["validate", "--no-timing", "scene.json"], _deep_json(1_000_000), 2,
     ["scene.json", ("nest", "deep", "depth")], max_output_bytes=64 << 10,
     desc="a million nested arrays (parsers recurse: stack overflow)")
case("crash-json-nesting-unclosed-1e6", "crash", ["validate", "--no-timing", "scene.json"],
     raw_writer("scene.json", "[" * 1_000_000), 2, ["scene.json"], max_output_bytes=64 << 10)
case("crash-manifest-nesting-1e6", "crash", ["inspect", "ref"],
     lambda ctx: (ctx.bake("ref"), ctx.write("ref/manifest.json",
                                             '{"lblight_version":"0.1.0","models":' + "[" * 1_000_000 + "]" * 1_000_000 + "}")),
     2, ["manifest.json"], max_output_bytes=64 << 10)

# ----------------------------------------------------------------------------------------- hang

HANG_T = 10

case("hang-scene-fifo-validate", "hang", ["validate", "--no-timing", "scene.json"],
     lambda ctx: ctx.fifo("scene.json"), 2, ["scene.json", NOT_REGULAR], timeout=HANG_T, max_seconds=5)
case("hang-scene-fifo-bake", "hang", ["bake", "scene.json", "-o", "out"],
     lambda ctx: ctx.fifo("scene.json"), 2, ["scene.json", NOT_REGULAR], timeout=HANG_T, max_seconds=5,
     must_not_exist=OUT_GONE)
case("hang-mesh-fifo-in-scene", "hang", ["validate", "--no-timing", "scene.json"],
     seq(lambda ctx: ctx.fifo("m.obj"), scene_writer(models=[mesh_model()])), 2, ["m.obj", NOT_REGULAR],
     timeout=HANG_T, max_seconds=5)
case("hang-mesh-fifo-voxelize", "hang", ["voxelize", "m.obj", "-o", "v.vdb"], lambda ctx: ctx.fifo("m.obj"), 2,
     ["m.obj", NOT_REGULAR], timeout=HANG_T, max_seconds=5, must_not_exist=["v.vdb", "*.tmp-*"])
case("hang-vdb-fifo-in-scene", "hang", ["validate", "--no-timing", "scene.json"],
     seq(lambda ctx: ctx.fifo("d.vdb"), scene_writer(models=[vdb_model()])), 2, ["d.vdb", NOT_REGULAR],
     timeout=HANG_T, max_seconds=5)
case("hang-compress-fifo", "hang", ["compress", "d.vdb", "--threshold", "0"], lambda ctx: ctx.fifo("d.vdb"), 2,
     ["d.vdb", NOT_REGULAR], timeout=HANG_T, max_seconds=5)
case("hang-inspect-fifo-vdb", "hang", ["inspect", "d.vdb"], lambda ctx: ctx.fifo("d.vdb"), 2,
     ["d.vdb", NOT_REGULAR], timeout=HANG_T, max_seconds=5)
case("hang-inspect-fifo-json", "hang", ["inspect", "scene.json"], lambda ctx: ctx.fifo("scene.json"), 2,
     ["scene.json", NOT_REGULAR], timeout=HANG_T, max_seconds=5)
case("hang-decompress-fifo-lbh", "hang", ["decompress", "m.lbh", "-o", "x.vdb"], lambda ctx: ctx.fifo("m.lbh"), 2,
     ["m.lbh", NOT_REGULAR], timeout=HANG_T, max_seconds=5, must_not_exist=["x.vdb", "*.tmp-*"])
case("hang-manifest-fifo-inspect", "hang", ["inspect", "ref"],
     lambda ctx: (ctx.bake("ref"), os.remove(ctx.p("ref/manifest.json")), ctx.fifo("ref/manifest.json")),
     2, ["manifest.json", NOT_REGULAR], timeout=HANG_T, max_seconds=5)
case("hang-manifest-fifo-compare", "hang", ["compare", "a", "b"],
     lambda ctx: (ctx.bake("a"), ctx.bake("b"), os.remove(ctx.p("b/manifest.json")), ctx.fifo("b/manifest.json")),
     2, ["manifest.json", NOT_REGULAR], timeout=HANG_T, max_seconds=5)
case("hang-manifest-model-file-is-fifo", "hang", ["compare", "a", "b"],
     lambda ctx: (ctx.bake("a"), ctx.bake("b"), os.remove(ctx.p("b/m.vdb")), ctx.fifo("b/m.vdb")),
     2, ["m.vdb", NOT_REGULAR], timeout=HANG_T, max_seconds=5,
     desc="the manifest's file entry is a plain name, but that file is a FIFO")
case("hang-bake-over-output-with-fifo-manifest", "hang", ["bake", "scene.json", "-o", "ref"],
     lambda ctx: (ctx.scene(), ctx.bake("ref"), os.remove(ctx.p("ref/manifest.json")), ctx.fifo("ref/manifest.json")),
     2, ["ref"], timeout=HANG_T, max_seconds=10, must_not_exist=["*.staging-*", "*.tmp-*"],
     check=lambda ctx, res: None if stat.S_ISFIFO(os.lstat(ctx.p("ref/manifest.json")).st_mode)
     else "the FIFO in the existing output folder was replaced",
     desc="-o names a folder whose manifest.json is a FIFO: refuse, do not block on it, do not replace it")
case("hang-scene-is-directory", "hang", ["validate", "--no-timing", "scene.json"],
     lambda ctx: ctx.mkdir("scene.json"), 2, ["scene.json", NOT_REGULAR], timeout=HANG_T,
     desc="a folder named scene.json")
case("hang-scene-is-dot", "hang", ["bake", "."], None, 2, [NOT_REGULAR], timeout=HANG_T,
     must_not_exist=["*-bake", "*.staging-*"])
case("hang-vdb-path-is-directory", "hang", ["validate", "--no-timing", "scene.json"],
     seq(lambda ctx: ctx.mkdir("d.vdb"), scene_writer(models=[vdb_model()])), 2, ["d.vdb", NOT_REGULAR],
     timeout=HANG_T)
for dev in ("/dev/zero", "/dev/urandom"):
    short = dev.rsplit("/", 1)[1]
    case("hang-scene-symlink-%s" % short, "hang", ["validate", "--no-timing", "scene.json"],
         (lambda d: lambda ctx: ctx.symlink(d, "scene.json"))(dev), 2, ["scene.json", NOT_REGULAR],
         timeout=HANG_T, max_seconds=5)
    case("hang-mesh-symlink-%s" % short, "hang", ["voxelize", "m.obj", "-o", "v.vdb"],
         (lambda d: lambda ctx: ctx.symlink(d, "m.obj"))(dev), 2, ["m.obj", NOT_REGULAR], timeout=HANG_T,
         max_seconds=5, must_not_exist=["v.vdb", "*.tmp-*"])
    case("hang-vdb-path-%s-in-scene" % short, "hang", ["validate", "--no-timing", "scene.json"],
         (lambda d: scene_writer(models=[vdb_model(path=d)]))(dev), 2, [dev, NOT_REGULAR], timeout=HANG_T,
         max_seconds=5)
    case("hang-compress-symlink-%s" % short, "hang", ["compress", "d.vdb", "--threshold", "0"],
         (lambda d: lambda ctx: ctx.symlink(d, "d.vdb"))(dev), 2, ["d.vdb", NOT_REGULAR], timeout=HANG_T,
         max_seconds=5, must_not_exist=["d.lbh", "*.tmp-*"])
    case("hang-inspect-lbh-symlink-%s" % short, "hang", ["inspect", "m.lbh"],
         (lambda d: lambda ctx: ctx.symlink(d, "m.lbh"))(dev), 2, ["m.lbh", NOT_REGULAR], timeout=HANG_T,
         max_seconds=5)
    case("hang-manifest-symlink-%s" % short, "hang", ["inspect", "ref"],
         (lambda d: lambda ctx: (ctx.bake("ref"), ctx.symlink(d, "ref/manifest.json")))(dev), 2,
         ["manifest.json", NOT_REGULAR], timeout=HANG_T, max_seconds=5)
case("hang-mesh-in-scene-urandom", "hang", ["validate", "--no-timing", "scene.json"],
     seq(lambda ctx: ctx.symlink("/dev/urandom", "noise.obj"), scene_writer(models=[mesh_model(path="noise.obj")])),
     2, ["noise.obj", NOT_REGULAR], timeout=HANG_T, max_seconds=5)
case("hang-decompress-urandom", "hang", ["decompress", "/dev/urandom", "-o", "x.vdb"], None, 2,
     ["/dev/urandom"], timeout=HANG_T, max_seconds=5, must_not_exist=["x.vdb", "*.tmp-*"])
case("hang-scene-dev-stdin-open-pipe", "hang", ["validate", "--no-timing", "/dev/stdin"], None, 2,
     ["/dev/stdin", NOT_REGULAR], stdin="open-pipe", timeout=HANG_T, max_seconds=5,
     desc="scene /dev/stdin while stdin is a pipe nobody writes to or closes")
case("hang-mtllib-fifo-ignored", "hang", ["voxelize", "m.obj", "-r", "8", "-o", "v.vdb"],
     lambda ctx: (ctx.fifo("m.mtl"), ctx.write("m.obj", "mtllib m.mtl\n" + TRIANGLE_OBJ)), 0, ["v.vdb"],
     timeout=HANG_T, desc="mtllib names a FIFO: lblight ignores .mtl files, so it must not open it")
case("hang-obj-sparse-20GB", "hang", ["voxelize", "m.obj", "-r", "8", "-o", "v.vdb"],
     lambda ctx: ctx.sparse("m.obj", 20 * GiB), 2, ["m.obj"], timeout=30, max_seconds=10,
     must_not_exist=["v.vdb", "*.tmp-*"], desc="a 20 GB OBJ of NUL bytes (sparse file): one endless line")
case("hang-vdb-sparse-20GB", "hang", ["inspect", "d.vdb"], lambda ctx: ctx.sparse("d.vdb", 20 * GiB), 2,
     ["d.vdb"], timeout=30, max_seconds=10)
case("hang-compress-vdb-lattice-at-int32-min", "hang", ["compress", "b.vdb", "--threshold", "0"],
     _compress_at(INT32_MIN, INT32_MIN), (0, 2), ["b.vdb"], needs_vdb=True, timeout=30,
     desc="compress a Vec3f grid whose lattice starts at -2^31")


def _long_bake(ctx):
    ctx.scene(models=[box_model(res=16)], lighting={"mode": "base", "solutions": "all"},
              solver={"iterations": 100000000})


SIG_T = 30
case("hang-sigterm-during-bake", "hang", ["bake", "scene.json", "-o", "out"], _long_bake, 130, [],
     signals=[(2.0, signal.SIGTERM)], timeout=SIG_T, max_seconds_after_signal=10, must_not_exist=OUT_GONE,
     desc="SIGTERM two seconds into a bake that would run for days: exit 130, nothing left")
case("hang-sigint-during-bake", "hang", ["bake", "scene.json", "-o", "out"], _long_bake, 130, [],
     signals=[(2.0, signal.SIGINT)], timeout=SIG_T, max_seconds_after_signal=10, must_not_exist=OUT_GONE)
case("hang-second-sigint-ends-at-once", "hang", ["bake", "scene.json", "-o", "out"], _long_bake, 130, [],
     signals=[(2.0, signal.SIGINT), (0.2, signal.SIGINT)], timeout=SIG_T, max_seconds_after_signal=2,
     must_not_exist=OUT_GONE)
case("hang-second-sigterm-ends-at-once", "hang", ["bake", "scene.json", "-o", "out"], _long_bake, 130, [],
     signals=[(2.0, signal.SIGTERM), (0.2, signal.SIGTERM)], timeout=SIG_T, max_seconds_after_signal=2,
     must_not_exist=OUT_GONE)
case("hang-sigint-then-sigterm", "hang", ["bake", "scene.json", "-o", "out"], _long_bake, 130, [],
     signals=[(2.0, signal.SIGINT), (0.2, signal.SIGTERM)], timeout=SIG_T, max_seconds_after_signal=2,
     must_not_exist=OUT_GONE)
case("hang-sigterm-while-blocked-on-fifo", "hang", ["validate", "--no-timing", "scene.json"],
     lambda ctx: ctx.fifo("scene.json"), 2, ["scene.json", NOT_REGULAR], timeout=HANG_T, max_seconds=3,
     desc="lblight must not block opening a FIFO at all: refused at once (SIGTERM during work: the sigint cases)")
case("hang-sigint-during-voxelize", "hang", ["voxelize", "m.obj", "-r", "400", "--supersample", "32", "-o", "v.vdb"],
     lambda ctx: ctx.write("m.obj", sphere_soup_obj()), 130, [], signals=[(3.0, signal.SIGINT)], timeout=SIG_T,
     max_seconds_after_signal=10, must_not_exist=["v.vdb", "*.tmp-*"])
case("hang-sigint-during-report", "hang", ["report", "scene.json", "-o", "rep"],
     lambda ctx: ctx.scene(models=[box_model(res=24, scale=0.9)], solver={"iterations": "auto", "tolerance": 1e-12}),
     130, [], signals=[(3.0, signal.SIGINT)], timeout=SIG_T, max_seconds_after_signal=10,
     must_not_exist=["rep", "*.staging-*", "*.tmp-*"])

# --------------------------------------------------------------------------------------- memory

for size, prec in [(2048, "float32"), (1024, "float64")]:
    case("memory-bench-size-%d-%s" % (size, prec), "memory", ["bench", "--size", str(size), "--precision", prec], None,
         1, ["--size %d" % size, "allowed"], max_seconds=5, desc="a bench size that cannot fit: refused up front")
case("memory-validate-dev-zero", "memory", ["validate", "--no-timing", "/dev/zero"], None, 2,
     ["/dev/zero", NOT_REGULAR], timeout=30, max_seconds=5)
case("memory-bake-dev-zero", "memory", ["bake", "/dev/zero", "-o", "out"], None, 2, ["/dev/zero", NOT_REGULAR],
     timeout=30, max_seconds=5, must_not_exist=OUT_GONE)
case("memory-inspect-dev-zero-json", "memory", ["inspect", "z.json"],
     lambda ctx: ctx.symlink("/dev/zero", "z.json"), 2, ["z.json", NOT_REGULAR], timeout=30, max_seconds=5)
case("memory-scene-sparse-100GB", "memory", ["validate", "--no-timing", "scene.json"],
     lambda ctx: ctx.sparse("scene.json", 100 * GiB), 2, ["scene.json", ("bytes", "large", "size")],
     timeout=30, max_seconds=5)


def _far_voxels(voxels):
    return lambda ctx: (ctx.write_vdb("far.vdb", [ctx.float_grid(voxels)]),
                        ctx.scene(models=[vdb_model(path="far.vdb")]))


case("memory-vdb-voxels-2e8-apart-validate", "memory", ["validate", "--no-timing", "scene.json"],
     _far_voxels([(0, 0, 0), (200_000_000, 0, 0)]), (1, 2), [("far.vdb", "/models/0/density"), MEMORY], needs_vdb=True, timeout=30,
     max_seconds=10, desc="two density voxels 2e8 apart: a 2e8-node lattice, refused up front")
case("memory-vdb-voxels-2e8-apart-bake", "memory", ["bake", "scene.json", "-o", "out"],
     _far_voxels([(0, 0, 0), (200_000_000, 0, 0)]), (1, 2), [("far.vdb", "/models/0/density"), MEMORY], needs_vdb=True, timeout=30,
     max_seconds=10, must_not_exist=OUT_GONE)
case("memory-vdb-voxels-1e5-cube-diagonal", "memory", ["bake", "scene.json", "-o", "out"],
     _far_voxels([(0, 0, 0), (100_000, 100_000, 100_000)]), (1, 2), [("far.vdb", "/models/0/density"), MEMORY], needs_vdb=True,
     timeout=30, max_seconds=10, must_not_exist=OUT_GONE, desc="1e15 lattice nodes")
case("memory-vdb-voxels-uint64-overflow", "memory", ["validate", "--no-timing", "scene.json"],
     _far_voxels([(-1_000_000_000,) * 3, (1_000_000_000,) * 3]), (1, 2), [("far.vdb", "/models/0/density"), MEMORY], needs_vdb=True,
     timeout=30, max_seconds=10, desc="(2e9)^3 nodes: the node count overflows 64 bits")
case("memory-vdb-int32-span-overflow", "memory", ["validate", "--no-timing", "scene.json"],
     _far_voxels([(-(2**30), 0, 0), (2**30, 0, 0)]), (1, 2), [("far.vdb", "/models/0/density")], needs_vdb=True, timeout=30,
     max_seconds=10, desc="x from -2^30 to 2^30: the extent 2^31+1 overflows int32 (never a negative size)")


def _tile_fill(lo, hi, name="density", vec=False):
    def setup(ctx):
        ctx.need_vdb()
        g = ctx.vdb.Vec3SGrid() if vec else ctx.vdb.FloatGrid()
        g.name = name
        g.fill(lo, hi, (1.0, 1.0, 1.0) if vec else 0.5, True)
        g.transform = ctx.vdb.createLinearTransform(voxelSize=0.1)
        ctx.write_vdb("tile.vdb", [g])
        if not vec:
            ctx.scene(models=[vdb_model(path="tile.vdb")])
    return setup


case("memory-vdb-density-4096-cube-tile", "memory", ["bake", "scene.json", "-o", "out"],
     _tile_fill((0, 0, 0), (4095, 4095, 4095)), (1, 2), [("tile.vdb", "/models/0/density"), MEMORY], needs_vdb=True, timeout=30,
     max_seconds=10, must_not_exist=OUT_GONE, desc="a few-KB .vdb whose active tiles cover 6.9e10 voxels")
case("memory-compress-2048-cube-vec3-tile", "memory", ["compress", "tile.vdb", "--threshold", "0.01"],
     _tile_fill((0, 0, 0), (2047, 2047, 2047), name="B00", vec=True), (1, 2), ["tile.vdb", MEMORY],
     needs_vdb=True, timeout=30, max_seconds=10, must_not_exist=["tile.lbh", "*.tmp-*"])
case("memory-procedural-1024-bake", "memory", ["bake", "scene.json", "-o", "out"],
     scene_writer(models=[box_model(res=1024)]), (1, 2), ["scene.json", MEMORY], timeout=30, max_seconds=10,
     must_not_exist=OUT_GONE, desc="the largest allowed procedural resolution: refused quickly, by name")
for _shape in ("cloud", "plant"):  # refused from a coarse copy of the shape, before generating it (minutes)
    case("memory-procedural-1024-" + _shape, "memory", ["bake", "scene.json", "-o", "out"],
         scene_writer(models=[{"name": "m", "density": {"type": "procedural", "shape": _shape, "resolution": 1024},
                               "material": "leaf"}]), (1, 2), ["scene.json", "/resolution", MEMORY], timeout=30,
         max_seconds=5, must_not_exist=OUT_GONE, desc="a procedural " + _shape + " that cannot fit: refused up front")
case("memory-procedural-1024-validate", "memory", ["validate", "--no-timing", "scene.json"],
     scene_writer(models=[box_model(res=1024)]), (1, 2), ["scene.json", MEMORY], timeout=30, max_seconds=10)
case("memory-mesh-2048-bake", "memory", ["bake", "scene.json", "-o", "out"],
     seq(raw_writer("m.obj", TETRA_OBJ), scene_writer(models=[mesh_model(resolution=2048)])), (1, 2),
     ["scene.json", MEMORY], timeout=30, max_seconds=10, must_not_exist=OUT_GONE)
case("memory-voxelize-8192", "memory", ["voxelize", "m.obj", "-r", "8192", "-o", "v.vdb"],
     raw_writer("m.obj", TETRA_OBJ), (1, 2), [MEMORY], timeout=30, max_seconds=10,
     must_not_exist=["v.vdb", "*.tmp-*"])
case("memory-voxelize-padding-1024-supersample-64", "memory",
     ["voxelize", "m.obj", "-r", "1024", "--padding", "1024", "--supersample", "64", "-o", "v.vdb"],
     raw_writer("m.obj", TETRA_OBJ), (1, 2), [MEMORY], timeout=30, max_seconds=10,
     must_not_exist=["v.vdb", "*.tmp-*"])
case("memory-bench-size-2048", "memory", ["bench", "--size", "2048", "--backend", "cpu"], None, (1, 2), [MEMORY],
     timeout=30, max_seconds=10, desc="2048^3 lattice: about a terabyte")
case("memory-bench-bandwidth-64GiB", "memory", ["bench", "--size", "8", "--backend", "cpu", "--bandwidth-mib", "65536"],
     None, (1, 2), [MEMORY], timeout=30, max_seconds=10)


def _million_models(ctx):
    parts = ['{"version":1,"lighting":{"mode":"base","solutions":"0"},"solver":{"iterations":1},"models":[']
    parts.append(",".join('{"name":"m%d","density":{"type":"procedural","shape":"box","resolution":4,'
                          '"density_scale":0.5},"material":"cloud"}' % i for i in range(1_000_000)))
    parts.append("]}")
    ctx.write("models.json", "".join(parts))


case("memory-scene-1e6-models", "memory", ["validate", "--no-timing", "models.json"], _million_models, (0, 2),
     ["models.json"], timeout=60, max_output_bytes=1 << 20,
     desc="a 120 MB scene of 10^6 models: validated or refused (size), never an OOM kill")
case("memory-scene-100MB-comment", "memory", ["validate", "--no-timing", "scene.json"],
     lambda ctx: ctx.json("scene.json", scene_obj(comment="x" * 100_000_000)), (0, 2), ["scene.json"],
     timeout=60, max_output_bytes=64 << 10)
case("memory-scene-50MB-model-name", "memory", ["validate", "--no-timing", "scene.json"],
     lambda ctx: ctx.json("scene.json", scene_obj(models=[box_model(name="n" * 50_000_000)])), 2,
     ["scene.json", "/models/0/name"], timeout=60, max_output_bytes=64 << 10,
     desc="the offending value is reported, but not echoed whole")
case("memory-lbh-dims-2p20-inspect", "memory", ["inspect", "m.lbh"], lambda ctx: lbh_variant(ctx, "m.lbh", "dims-2p20"),
     2, ["m.lbh"], timeout=30, max_seconds=5, desc="header claims 2^60 nodes (CRC fixed up)")
case("memory-lbh-dims-2p20-decompress", "memory", ["decompress", "m.lbh", "-o", "x.vdb"],
     lambda ctx: lbh_variant(ctx, "m.lbh", "dims-2p20"), 2, ["m.lbh"], timeout=30, max_seconds=5,
     must_not_exist=["x.vdb", "*.tmp-*"])
case("memory-lbh-coeff-count-2p60", "memory", ["decompress", "m.lbh", "-o", "x.vdb"],
     lambda ctx: lbh_variant(ctx, "m.lbh", "coeff-count-huge"), 2, ["m.lbh"], timeout=30, max_seconds=5,
     must_not_exist=["x.vdb", "*.tmp-*"])
case("memory-manifest-sparse-1GB", "memory", ["inspect", "ref"],
     lambda ctx: (ctx.bake("ref"), ctx.sparse("ref/manifest.json", GiB)), 2, ["manifest.json"], timeout=30,
     max_seconds=5)
case("memory-threads-4096", "memory", ["bake", "scene.json", "--threads", "4096", "-o", "out"], scene_writer(),
     (0, 1), [], timeout=60,
     desc="--threads 4096 (the documented maximum) under a 4 GiB address space: bakes or fails cleanly")

# ------------------------------------------------------------------------------- partial-output

def _check_trailing_slash(ctx, res):
    if res.returncode == 0:
        return None if os.path.exists(ctx.p("out/manifest.json")) else "exit 0 but out/manifest.json missing"
    return "failed, yet left the output folder out/ behind" if os.path.exists(ctx.p("out")) else None


case("partial-trailing-slash", "partial-output", ["bake", "scene.json", "-o", "out/"], scene_writer(), (0, 2), [],
     must_not_exist=["*.staging-*", "*.tmp-*", "out/.*", "..*"], check=_check_trailing_slash,
     desc="-o out/ works, or fails cleanly before solving (exit 2) leaving nothing")
case("partial-trailing-slash-over-previous", "partial-output", ["bake", "scene.json", "-o", "ref/"],
     lambda ctx: (ctx.scene(), ctx.bake("ref")), (0, 2), [], must_not_exist=["*.staging-*", "*.tmp-*"],
     check=lambda ctx, res: None if os.path.exists(ctx.p("ref/manifest.json")) else "ref/manifest.json is gone")
case("partial-readonly-parent", "partial-output", ["bake", "scene.json", "-o", "ro/out"],
     lambda ctx: (ctx.scene(), ctx.mkdir("ro"), os.chmod(ctx.p("ro"), 0o555)), (1, 2), ["ro"],
     run_as_nobody=True, must_not_exist=["ro/out", "ro/.out.staging-*", "*.tmp-*"], max_seconds=10,
     desc="output inside a read-only folder (run as nobody when root): fail before solving, naming it")
case("partial-output-under-a-file", "partial-output", ["bake", "scene.json", "-o", "note.txt/out"],
     lambda ctx: (ctx.scene(), ctx.write("note.txt", "keep me\n")), (1, 2), ["note.txt"], unchanged=["note.txt"],
     max_seconds=10)
case("partial-output-is-existing-file", "partial-output", ["bake", "scene.json", "-o", "note.txt"],
     lambda ctx: (ctx.scene(), ctx.write("note.txt", "keep me\n")), 2, ["note.txt"], unchanged=["note.txt"])
case("partial-output-is-scene-file", "partial-output", ["bake", "scene.json", "-o", "scene.json"], scene_writer(), 2,
     ["scene.json"], unchanged=["scene.json"])
case("partial-output-is-cwd", "partial-output", ["bake", "scene.json", "-o", "."], scene_writer(), 2,
     [], unchanged=["scene.json"], desc="-o . (the folder holding the scene)")
case("partial-output-empty-string", "partial-output", ["bake", "scene.json", "-o", ""], scene_writer(), 2,
     [("-o", "output")], unchanged=["scene.json"])
case("partial-output-root", "partial-output", ["bake", "scene.json", "-o", "/"], scene_writer(), 2, ["/"],
     max_seconds=10)
case("partial-output-dir-with-note", "partial-output", ["bake", "scene.json", "-o", "out"],
     lambda ctx: (ctx.scene(), ctx.write("out/notes.txt", "mine\n")), 2, ["out"], unchanged=["out/notes.txt"])
case("partial-previous-bake-with-note", "partial-output", ["bake", "scene.json", "-o", "ref"],
     lambda ctx: (ctx.scene(), ctx.bake("ref"), ctx.write("ref/notes.txt", "mine\n")), 2, ["notes.txt"],
     unchanged=["ref/notes.txt", "ref/manifest.json"])
case("partial-previous-bake-with-subfolder", "partial-output", ["bake", "scene.json", "-o", "ref"],
     lambda ctx: (ctx.scene(), ctx.bake("ref"), ctx.write("ref/sub/x.vdb", "x")), 2, ["sub"],
     unchanged=["ref/sub/x.vdb"])
case("partial-previous-bake-with-symlinked-vdb", "partial-output", ["bake", "scene.json", "-o", "ref"],
     lambda ctx: (ctx.scene(), ctx.bake("ref"), ctx.write("keep.vdb", "precious"),
                  ctx.symlink("../keep.vdb", "ref/other.vdb")), 2, ["other.vdb"], unchanged=["keep.vdb"])
case("partial-foreign-manifest", "partial-output", ["bake", "scene.json", "-o", "out"],
     lambda ctx: (ctx.scene(), ctx.json("out/manifest.json", {"name": "someone else's"})), 2, ["out"],
     unchanged=["out/manifest.json"])
case("partial-report-folder-as-bake-output", "partial-output", ["bake", "scene.json", "-o", "rep"],
     lambda ctx: (ctx.scene(), ctx.json("rep/report.json", {"curves": [], "references": []}),
                  ctx.write("rep/report.csv", "x\n")), 2, ["rep"], unchanged=["rep/report.json"])
case("partial-bake-replaces-previous", "partial-output", ["bake", "scene.json", "-o", "ref"],
     lambda ctx: (ctx.scene(), ctx.bake("ref")), 0, [], must_exist=["ref/manifest.json", "ref/m.vdb"],
     desc="control: a previous bake is replaced, nothing hidden left beside it")
case("partial-interrupt-keeps-previous", "partial-output", ["bake", "scene.json", "-o", "ref"],
     lambda ctx: (_long_bake(ctx), ctx.bake("ref")), 130, [], signals=[(2.0, signal.SIGINT)], timeout=SIG_T,
     unchanged=["ref/manifest.json", "ref/m.vdb"], max_seconds_after_signal=10,
     desc="an interrupted bake over a previous one leaves the previous one as it was")
case("partial-second-model-fails", "partial-output", ["bake", "scene.json", "-o", "out"],
     lambda ctx: (damaged_vdb(ctx, "bad.vdb", "cut-half"),
                  ctx.scene(models=[box_model("first"), vdb_model(path="bad.vdb", name="second")])),
     2, ["bad.vdb"], must_not_exist=OUT_GONE, desc="model 2's .vdb is cut short: nothing of model 1 left either")
case("partial-stale-staging-dead-pid-cleaned", "partial-output", ["bake", "scene.json", "-o", "out"],
     lambda ctx: (ctx.scene(), ctx.write(".out.staging-%d-0/m.vdb" % ctx.dead_pid(), "stale")), 0, [],
     must_exist=["out/manifest.json"], must_not_exist=["*.staging-*", "*.tmp-*"],
     desc="a staging folder left by a killed bake (its PID is dead) is removed by the next bake")
case("partial-stale-staging-old-dead-pid-cleaned", "partial-output", ["bake", "scene.json", "-o", "out"],
     lambda ctx: (ctx.scene(), ctx.write("..out.staging-%d-0.old/m.vdb" % ctx.dead_pid(), "stale")), 0, [],
     must_exist=["out/manifest.json"], must_not_exist=["*.staging-*", "*.tmp-*"],
     desc="the '.old' copy a bake killed during commit leaves behind is removed too")


def _live_staging(ctx):
    ctx.scene()
    ctx.write(".out.staging-%d-0/m.vdb" % os.getpid(), "busy")


case("partial-staging-of-live-pid-kept", "partial-output", ["bake", "scene.json", "-o", "out"], _live_staging, 0, [],
     must_exist=["out/manifest.json"], default_must_not_exist=False, must_not_exist=["*.tmp-*"],
     check=lambda ctx, res: None if os.path.exists(ctx.p(".out.staging-%d-0/m.vdb" % os.getpid()))
     else "deleted the staging folder of a process that is still running",
     desc="a staging folder whose PID is alive may belong to a running bake: never delete it")


def _staging_symlink_victim(ctx):
    ctx.scene()
    ctx.write("victim/precious.txt", "do not delete\n")
    ctx.symlink("victim", ".out.staging-%d-0" % ctx.dead_pid())


case("partial-stale-staging-symlink-not-followed", "partial-output", ["bake", "scene.json", "-o", "out"],
     _staging_symlink_victim, (0, 2), [], default_must_not_exist=False, must_not_exist=["*.tmp-*"],
     unchanged=["victim/precious.txt"],
     desc="a 'stale staging folder' that is a symlink to another folder: cleaning must not delete through it")
case("partial-voxelize-into-missing-folder", "partial-output", ["voxelize", "m.obj", "-r", "8", "-o", "nodir/v.vdb"],
     raw_writer("m.obj", TRIANGLE_OBJ), (0, 1, 2), [], must_not_exist=["*.tmp-*", "nodir/.*"],
     check=lambda ctx, res: None if res.returncode != 0 or os.path.exists(ctx.p("nodir/v.vdb"))
     else "exit 0 but nodir/v.vdb missing")
case("partial-voxelize-output-is-directory", "partial-output", ["voxelize", "m.obj", "-r", "8", "-o", "v.vdb"],
     lambda ctx: (ctx.write("m.obj", TRIANGLE_OBJ), ctx.write("v.vdb/keep.txt", "x")), 2, ["v.vdb"],
     unchanged=["v.vdb/keep.txt"])
case("partial-voxelize-bad-mesh-leaves-nothing", "partial-output", ["voxelize", "m.obj", "-r", "8", "-o", "v.vdb"],
     raw_writer("m.obj", TRIANGLE_OBJ + "v nan 0 0\n"), 2, ["m.obj"], must_not_exist=["v.vdb", "*.tmp-*"])
case("partial-voxelize-keeps-previous-on-failure", "partial-output",
     ["voxelize", "m.obj", "-r", "8", "-o", "v.vdb"],
     lambda ctx: (ctx.write("m.obj", TRIANGLE_OBJ.replace("f 1 2 3", "f 1 2 9")), ctx.write("v.vdb", "previous")),
     2, ["m.obj"], unchanged=["v.vdb"])
case("partial-compress-output-over-input", "partial-output", ["compress", "d.vdb", "--threshold", "0", "-o", "d.vdb"],
     lambda ctx: ctx.small_vdb("d.vdb"), 2, ["d.vdb"], unchanged=["d.vdb"],
     desc="compress -o the input itself: refuse rather than overwrite the .vdb with an .lbh")
case("partial-decompress-output-over-input", "partial-output", ["decompress", "m.lbh", "-o", "m.lbh"],
     lambda ctx: ctx.small_lbh("m.lbh"), 2, ["m.lbh"], unchanged=["m.lbh"])
case("partial-compress-output-under-file", "partial-output",
     ["compress", "d.vdb", "--threshold", "0", "-o", "note.txt/d.lbh"],
     lambda ctx: (ctx.small_vdb("d.vdb"), ctx.write("note.txt", "x")), (1, 2), ["note.txt"],
     unchanged=["note.txt"])
case("partial-decompress-corrupt-leaves-nothing", "partial-output", ["decompress", "m.lbh", "-o", "x.vdb"],
     lambda ctx: lbh_variant(ctx, "m.lbh", "bad-section-crc"), 2, ["m.lbh"], must_not_exist=["x.vdb", "*.tmp-*"])
case("partial-report-into-dir-with-note", "partial-output", ["report", "scene.json", "-o", "rep"],
     lambda ctx: (ctx.scene(), ctx.write("rep/notes.txt", "mine")), 2, ["rep"], unchanged=["rep/notes.txt"])
case("partial-report-into-previous-bake", "partial-output", ["report", "scene.json", "-o", "ref"],
     lambda ctx: (ctx.scene(), ctx.bake("ref")), 2, ["ref"], unchanged=["ref/manifest.json"])
case("partial-bake-stdout-full", "partial-output", ["bake", "scene.json", "-o", "out"], scene_writer(), 1, [],
     stdout_file="/dev/full",
     desc="the summary cannot be written (stdout is /dev/full): the run must not report success")

# ------------------------------------------------------------------------------------- wrong-ok


def _compare_poison(side, value, where=(3, 3, 3), grid="B06", both=False):
    def setup(ctx):
        ctx.bake("a")
        ctx.bake("b")
        for d in (("a", "b") if both else (side,)):
            ctx.edit_vdb(d + "/m.vdb", replace_grid(grid, lambda g: set_voxel(g, where, value)))
    return setup


NAN = float("nan")
INF = float("inf")
for nm, side, val, both in [("other-nan", "b", (NAN, 1.0, 1.0), False), ("reference-nan", "a", (NAN, 1.0, 1.0), False),
                            ("other-inf", "b", (INF, 1.0, 1.0), False), ("reference-minus-inf", "a", (1.0, -INF, 1.0), False),
                            ("both-nan-same-voxel", "b", (NAN, NAN, NAN), True),
                            ("both-inf-same-voxel", "b", (INF, INF, INF), True),
                            ("other-nan-in-margin", "b", (0.0, 0.0, NAN), False)]:
    where = (-1, -1, -1) if "margin" in nm else (3, 3, 3)
    case("wrong-ok-compare-%s" % nm, "wrong-ok", ["compare", "a", "b"], _compare_poison(side, val, where, both=both),
         (1, 2), ["B06"], needs_vdb=True, desc="NaN/Inf in a grid must count as a difference")
case("wrong-ok-compare-nan-huge-tolerance", "wrong-ok", ["compare", "a", "b", "--tolerance", "1e30"],
     _compare_poison("b", (NAN, 1.0, 1.0)), (1, 2), ["B06"], needs_vdb=True)
case("wrong-ok-compare-same-bake", "wrong-ok", ["compare", "a", "b", "--tolerance", "0"],
     lambda ctx: (ctx.bake("a"), ctx.bake("b")), 0, ["B06"], desc="control: identical bakes compare equal")
case("wrong-ok-compare-small-difference", "wrong-ok", ["compare", "a", "b"],
     _compare_poison("b", (100.0, 100.0, 100.0)), 1, ["B06"], needs_vdb=True, desc="control: a real difference")
case("wrong-ok-compare-other-lacks-solution", "wrong-ok", ["compare", "a", "b"],
     lambda ctx: (ctx.bake("a"), ctx.bake("b"),
                  ctx.edit_manifest("b", lambda m: m["models"][0].__setitem__(
                      "solutions", [s for s in m["models"][0]["solutions"] if s["grid"] != "B06"])),
                  ctx.edit_vdb("b/m.vdb", lambda gs: [g for g in gs if g.name != "B06"])),
     2, ["B06"], needs_vdb=True)


# relight reads a bake with the checks compare has (issue 56 item 3: one validation shared by the
# readers of a bake's grids): a damaged, renamed or foreign grid is refused, never relit.
def _relight_setup(edit=None, manifest=None):
    def setup(ctx):
        ctx.bake("ref")
        if edit:
            ctx.edit_vdb("ref/m.vdb", edit)
        if manifest:
            ctx.edit_manifest("ref", manifest)
    return setup


def _swap_names(grids):
    for g in grids:
        g.name = {"B00": "B06", "B06": "B00"}.get(g.name, g.name)
    return grids


def _b06_transform(ctx):
    def fn(grids):
        for g in grids:
            if g.name == "B06":
                g.transform = ctx.vdb.createLinearTransform(voxelSize=0.37)
        return grids
    return fn


RELIGHT = ["relight", "ref", "-o", "f.vdb", "--sun-elevation", "90", "--ambient", "0.1"]
case("wrong-ok-relight-nan", "wrong-ok", RELIGHT,
     _relight_setup(edit=replace_grid("B06", lambda g: set_voxel(g, (3, 3, 3), (NAN, 1.0, 1.0)))), 2,
     [("m.vdb",), ("non-finite",)], needs_vdb=True, must_not_exist=["f.vdb", "*.tmp-*"])
case("wrong-ok-relight-swapped-names", "wrong-ok", RELIGHT, _relight_setup(edit=_swap_names), 2,
     [("m.vdb",), ("lblight_solution",)], needs_vdb=True, must_not_exist=["f.vdb", "*.tmp-*"])
case("wrong-ok-relight-other-transform", "wrong-ok", RELIGHT,
     lambda ctx: (ctx.bake("ref"), ctx.edit_vdb("ref/m.vdb", _b06_transform(ctx))), 2,
     [("m.vdb",), ("transform",)], needs_vdb=True, must_not_exist=["f.vdb", "*.tmp-*"])
case("wrong-ok-relight-other-lattice", "wrong-ok", RELIGHT,
     _relight_setup(manifest=lambda m: m["models"][0]["lattice"].__setitem__(
         "dims", [d + 2 for d in m["models"][0]["lattice"]["dims"]])), 2,
     [("m.vdb",), ("lattice box",)], must_not_exist=["f.vdb", "*.tmp-*"])
case("wrong-ok-relight-control", "wrong-ok", RELIGHT, _relight_setup(), 0, ["f.vdb"],
     desc="control: the same bake undamaged relights")
case("wrong-ok-compare-empty-manifest", "wrong-ok", ["compare", "a", "b"],
     lambda ctx: (ctx.bake("a"), ctx.bake("b"), ctx.edit_manifest("a", lambda m: m.__setitem__("models", []))),
     2, [("manifest.json",), ("no model",)])
for nm, extra in [("max-photons-negative", ["--max-photons", "-1"]),
                  ("max-photons-2p64", ["--max-photons", "18446744073709551616"]),
                  ("seed-negative", ["--seed", "-5"]),
                  ("cap-below-batches", ["--photons-per-batch", "1073741824", "--max-photons", "1"])]:
    case("message-truth-%s" % nm, "message", ["truth", "scene.json", "-o", "out"] + extra, scene_writer(), 2,
         [extra[-2] if nm != "cap-below-batches" else "--max-photons"], max_seconds=5, must_not_exist=OUT_GONE)
case("message-scene-nul-in-path", "message", ["bake", "scene.json", "-o", "out"],
     lambda ctx: (ctx.small_vdb("ok.vdb"), ctx.scene(models=[vdb_model(path="ok.vdb\x00/../../etc/passwd")])),
     2, [("scene.json",), ("control character",)], needs_vdb=True, must_not_exist=OUT_GONE)


def _shift_transform(ctx):
    ctx.bake("a")
    ctx.bake("b")

    def fn(grids):
        for g in grids:
            g.transform = ctx.vdb.createLinearTransform(voxelSize=0.5)
        return grids
    ctx.edit_vdb("b/m.vdb", fn)


case("wrong-ok-compare-other-transform", "wrong-ok", ["compare", "a", "b"], _shift_transform, (1, 2),
     [("transform", "voxel size", "world")], needs_vdb=True,
     desc="same index box, values and manifest, but the other .vdb's voxels are 4x larger in world space")
case("wrong-ok-compress-duplicate-B00", "wrong-ok", ["compress", "dup.vdb", "--threshold", "0"],
     lambda ctx: (ctx.small_vdb("d.vdb"),
                  ctx.edit_vdb("d.vdb", lambda gs: gs + [g.deepCopy() for g in gs if g.name == "B00"]),
                  os.rename(ctx.p("d.vdb"), ctx.p("dup.vdb"))),
     2, ["dup.vdb", "B00"], needs_vdb=True, must_not_exist=["dup.lbh", "*.tmp-*"])
case("wrong-ok-compress-grids-listed-twice", "wrong-ok", ["compress", "d.vdb", "--threshold", "0", "--grids", "B00,B00"],
     lambda ctx: ctx.small_vdb("d.vdb"), 2, ["B00"], must_not_exist=["d.lbh", "*.tmp-*"],
     desc="--grids B00,B00 would store two solutions of one name")
case("wrong-ok-compress-unknown-grid", "wrong-ok", ["compress", "d.vdb", "--threshold", "0", "--grids", "B00,NOPE"],
     lambda ctx: ctx.small_vdb("d.vdb"), 2, ["NOPE"], must_not_exist=["d.lbh", "*.tmp-*"])
case("wrong-ok-compress-float-grid-asked", "wrong-ok", ["compress", "d.vdb", "--threshold", "0", "--grids", "density"],
     lambda ctx: ctx.small_vdb("d.vdb"), 2, ["density"], must_not_exist=["d.lbh", "*.tmp-*"])
case("wrong-ok-compress-no-vec3-grids", "wrong-ok", ["compress", "d.vdb", "--threshold", "0"],
     lambda ctx: ctx.write_vdb("d.vdb", [ctx.float_grid([(0, 0, 0)])]), 2, ["d.vdb"], needs_vdb=True,
     must_not_exist=["d.lbh", "*.tmp-*"])
case("wrong-ok-compress-nan-value", "wrong-ok", ["compress", "b.vdb", "--threshold", "0.01", "--relative"],
     lambda ctx: ctx.write_vdb("b.vdb", [ctx.vec3_grid(box_voxels(0, 0, 0, 4) + [(1, 1, 1, (NAN, 0.0, 0.0))])]),
     2, ["b.vdb", "B00"], needs_vdb=True, must_not_exist=["b.lbh", "*.tmp-*"])
case("wrong-ok-compress-huge-finite-values", "wrong-ok", ["compress", "big.vdb", "--threshold", "0"],
     lambda ctx: ctx.write_vdb("big.vdb", [ctx.vec3_grid(box_voxels(0, 0, 0, 4), value=(3e38, 3e38, 3e38))]),
     (0, 2), ["big.vdb"], needs_vdb=True, check=check_huge_values_roundtrip,
     desc="values of 3e38 (finite): Haar sums overflow float; refuse, or decode them back finite")
case("wrong-ok-compress-relative-threshold-above-1", "wrong-ok",
     ["compress", "d.vdb", "--threshold", "2", "--relative"], lambda ctx: ctx.small_vdb("d.vdb"), 2,
     ["threshold"], must_not_exist=["d.lbh", "*.tmp-*"], desc="scene-format.md: relative thresholds are 0..1")
case("wrong-ok-compress-threshold-0-lossless", "wrong-ok", ["compress", "ref/m.vdb", "--threshold", "0"],
     lambda ctx: ctx.bake("ref"), 0, [], check=check_lossless_roundtrip,
     desc="--help: '0 is lossless'; decompressed grids must equal the originals (compare --tolerance 0)")
case("wrong-ok-report-iterations-7", "wrong-ok", ["report", "scene.json", "--iterations", "7", "-o", "rep"],
     scene_writer(solver={"iterations": "auto"}), (0, 2), [], check=check_report_iterations(7),
     desc="--iterations 7 is honoured (no curve past step 7) or refused, never ignored")
case("wrong-ok-report-iterations-paper", "wrong-ok", ["report", "scene.json", "--iterations", "paper", "-o", "rep"],
     scene_writer(solver={"iterations": "auto"}), (0, 2), [], check=check_report_iterations(2 * 10),
     desc="paper = 2 x longest lattice edge (10 for a resolution-8 box with margin 1)")


def _small_far(ctx):
    ctx.write("m.obj", "o leaves\nv 0 0 0\nv 0.01 0 0\nv 0 0.01 0\nv 100 100 100\nv 101 100 100\nv 100 101 100\n"
                       "f 1 2 3\nf 4 5 6\n")
    ctx.write("far.obj", "o leaves\nv 100 100 100\nv 101 100 100\nv 100 101 100\nf 1 2 3\n")


case("wrong-ok-voxelize-small-triangle-with-far-one", "wrong-ok",
     ["voxelize", "m.obj", "-r", "64", "--bounds"] + BOUNDS_SF + ["-o", "v.vdb"], _small_far, 0, [],
     check=check_small_triangle_kept, desc="a 0.01 triangle at the origin and a 1.0 one 100 away: both kept")
case("wrong-ok-voxelize-small-triangle-default-bounds", "wrong-ok", ["voxelize", "m.obj", "-r", "64", "-o", "v.vdb"],
     _small_far, 0, [],
     check=lambda ctx, res: None if res.returncode != 0 or grid_active_voxels(ctx, "v.vdb", "density") >= 2
     else "only %d density voxel(s): a triangle was dropped" % grid_active_voxels(ctx, "v.vdb", "density"))
case("wrong-ok-voxelize-tiny-triangle-far-from-origin", "wrong-ok", ["voxelize", "m.obj", "-r", "8", "-o", "v.vdb"],
     raw_writer("m.obj", "o leaves\nv 1000000 1000000 1000000\nv 1000000.001 1000000 1000000\n"
                         "v 1000000 1000000.001 1000000\nf 1 2 3\n"), (0, 2), ["m.obj"],
     check=check_tiny_far_triangle,
     desc="a 1e-3 triangle at 1e6: float32 coordinates collapse it; voxelize it or refuse it, never an empty grid")
case("wrong-ok-static-sun-huge-direction", "wrong-ok", ["bake", "scene.json", "-o", "out"],
     lambda ctx: (ctx.scene(lighting={"mode": "static", "sun": {"direction": [1e308, 1e308, 1e308]}}),
                  ctx.scene(rel="unit.json", lighting={"mode": "static", "sun": {"direction": [1, 1, 1]}})),
     (0, 2), [], check=check_same_as_bake("unit.json"),
     desc="direction [1e308]*3 normalises to the same sun as [1,1,1] (or is refused); never NaN light")
case("wrong-ok-static-sun-zero-direction", "wrong-ok", ["bake", "scene.json", "-o", "out"],
     scene_writer(lighting={"mode": "static", "sun": {"direction": [0, 0, 0]}}), 2,
     ["scene.json", "/lighting/sun/direction"], must_not_exist=OUT_GONE)
case("wrong-ok-static-sun-tiny-direction", "wrong-ok", ["bake", "scene.json", "-o", "out"],
     lambda ctx: (ctx.scene(lighting={"mode": "static", "sun": {"direction": [1e-320, 0, 1e-320]}}),
                  ctx.scene(rel="unit.json", lighting={"mode": "static", "sun": {"direction": [1, 0, 1]}})),
     (0, 2), [], check=check_same_as_bake("unit.json"), desc="a denormal direction vector")
case("wrong-ok-vdb-density-two-grids-named-density", "wrong-ok", ["validate", "--no-timing", "scene.json"],
     lambda ctx: (ctx.write_vdb("d.vdb", [ctx.float_grid([(0, 0, 0)]), ctx.float_grid([(5, 5, 5)], value=0.9)]),
                  ctx.scene(models=[vdb_model()])), 2, [VDB_NAMED, "density"], needs_vdb=True,
     desc="two grids named 'density': which one is baked? refuse as ambiguous")
for nm, voxels, frag in [("negative", [(0, 0, 0, -0.5)], "density"), ("nan", [(0, 0, 0, NAN)], "density"),
                         ("inf", [(0, 0, 0, INF)], "density"), ("above-1", [(0, 0, 0, 1.5)], "density")]:
    case("wrong-ok-vdb-density-%s" % nm, "wrong-ok", ["bake", "scene.json", "-o", "out"],
         (lambda v: lambda ctx: (ctx.write_vdb("d.vdb", [ctx.float_grid(v)]), ctx.scene(models=[vdb_model()])))(voxels),
         2, [VDB_NAMED, frag], needs_vdb=True, must_not_exist=OUT_GONE)
case("wrong-ok-vdb-density-background-nonzero", "wrong-ok", ["validate", "--no-timing", "scene.json"],
     lambda ctx: (ctx.write_vdb("d.vdb", [ctx.float_grid([(0, 0, 0)], background=0.25)]), ctx.scene(models=[vdb_model()])),
     2, [VDB_NAMED, "background"], needs_vdb=True)
case("wrong-ok-vdb-density-frustum-transform", "wrong-ok", ["validate", "--no-timing", "scene.json"],
     lambda ctx: (ctx.need_vdb(), ctx.write_vdb("d.vdb", [ctx.float_grid(
         [(0, 0, 0)], transform=ctx.vdb.createFrustumTransform((0, 0, 0), (10, 10, 10), 0.5, 2.0, 0.1))]),
         ctx.scene(models=[vdb_model()])), 2, [VDB_NAMED, ("linear", "transform")], needs_vdb=True)
case("wrong-ok-vdb-density-anisotropic-voxels", "wrong-ok", ["validate", "--no-timing", "scene.json"],
     lambda ctx: (ctx.need_vdb(), ctx.write_vdb("d.vdb", [ctx.float_grid(box_voxels(0, 0, 0), transform=ctx.vdb.createLinearTransform(
         [[0.1, 0, 0, 0], [0, 0.4, 0, 0], [0, 0, 0.1, 0], [0, 0, 0, 1]]))]),
                  ctx.scene(models=[vdb_model()])), 0, ["not cubic"],
     needs_vdb=True, desc="voxels 4x taller than wide: the D3Q19 lattice assumes cubic nodes; baked as cubes, with "
                          "a warning (docs/scene-format.md)")
case("wrong-ok-vdb-density-is-vec3", "wrong-ok", ["validate", "--no-timing", "scene.json"],
     lambda ctx: (ctx.write_vdb("d.vdb", [ctx.vec3_grid([(0, 0, 0)], name="density")]), ctx.scene(models=[vdb_model()])),
     2, [VDB_NAMED, "float"], needs_vdb=True)
case("wrong-ok-vdb-density-empty-grid", "wrong-ok", ["bake", "scene.json", "-o", "out"],
     lambda ctx: (ctx.write_vdb("d.vdb", [ctx.float_grid([])]), ctx.scene(models=[vdb_model()])), 2,
     [VDB_NAMED, "density"], needs_vdb=True, must_not_exist=OUT_GONE)
case("wrong-ok-vdb-wood-grid-vec3", "wrong-ok", ["validate", "--no-timing", "scene.json"],
     lambda ctx: (ctx.write_vdb("d.vdb", [ctx.float_grid(box_voxels(0, 0, 0)), ctx.vec3_grid([(0, 0, 0)], name="wood")]),
                  ctx.scene(models=[vdb_model(wood_grid="wood")])), 2, [VDB_NAMED, "wood"], needs_vdb=True)
case("wrong-ok-vdb-wood-grid-other-transform", "wrong-ok", ["validate", "--no-timing", "scene.json"],
     lambda ctx: (ctx.write_vdb("d.vdb", [ctx.float_grid(box_voxels(0, 0, 0)),
                                          ctx.float_grid([(0, 0, 0)], name="wood", value=1.0, voxel_size=0.2)]),
                  ctx.scene(models=[vdb_model(wood_grid="wood")])), 2, [VDB_NAMED, "wood", "transform"],
     needs_vdb=True, desc="scene-format.md: the wood grid must have the same transform")
case("wrong-ok-iterations-0", "wrong-ok", ["bake", "scene.json", "--iterations", "0", "-o", "out"], scene_writer(), 2,
     ["--iterations"], must_not_exist=OUT_GONE)
case("wrong-ok-iterations-overflow", "wrong-ok", ["bake", "scene.json", "--iterations", "4294967297", "-o", "out"],
     scene_writer(), 2, ["--iterations"], must_not_exist=OUT_GONE, desc="2^32+1 must not wrap to 1")
case("wrong-ok-iterations-float-in-scene", "wrong-ok", ["validate", "--no-timing", "scene.json"],
     scene_writer(solver={"iterations": 4.5}), 2, ["scene.json", "/solver/iterations"])
case("wrong-ok-iterations-1e3-in-scene", "wrong-ok", ["validate", "--no-timing", "scene.json"],
     scene_writer(solver={"iterations": 1e3}), (0, 2), ["scene.json"],
     desc="1e3 is the integer 1000 written as a float: accepted as 1000 or refused by pointer")
case("wrong-ok-bicgstab-fixed-steps", "wrong-ok", ["bake", "scene.json", "-o", "out"],
     scene_writer(solver={"iterations": 7, "method": "bicgstab"}), 2, ["scene.json", "/solver"],
     must_not_exist=OUT_GONE, desc="scene-format.md: bicgstab needs iterations auto")
case("wrong-ok-solutions-reversed-range", "wrong-ok", ["bake", "scene.json", "--solutions", "7-5", "-o", "out"],
     scene_writer(), 2, ["7-5"], must_not_exist=OUT_GONE)
case("wrong-ok-solutions-empty-items", "wrong-ok", ["bake", "scene.json", "--solutions", "0,,6,", "-o", "out"],
     scene_writer(), 2, ["--solutions"], must_not_exist=OUT_GONE)
case("wrong-ok-solutions-with-sun", "wrong-ok", ["validate", "--no-timing", "scene.json"],
     scene_writer(lighting={"mode": "base", "solutions": "0,6", "sun": {"elevation": 40, "azimuth": 0}}), 2,
     ["scene.json", "/lighting"])
case("wrong-ok-sun-range-inverted", "wrong-ok", ["validate", "--no-timing", "scene.json"],
     scene_writer(lighting={"mode": "base", "sun_range": {"min_elevation": 60, "max_elevation": 10}}), 2,
     ["scene.json", "/lighting/sun_range"])
case("wrong-ok-density-scale-above-1", "wrong-ok", ["bake", "scene.json", "-o", "out"],
     scene_writer(models=[box_model(scale=1.5)]), 2, ["scene.json", "density_scale"], must_not_exist=OUT_GONE)
case("wrong-ok-mesh-bounds-inverted", "wrong-ok", ["validate", "--no-timing", "scene.json"],
     seq(raw_writer("m.obj", TRIANGLE_OBJ), scene_writer(models=[mesh_model(bounds={"min": [1, 1, 1], "max": [0, 0, 0]})])),
     2, ["scene.json", "/models/0/density/bounds"])
case("wrong-ok-mesh-bounds-overflow", "wrong-ok", ["validate", "--no-timing", "scene.json"],
     seq(raw_writer("m.obj", TRIANGLE_OBJ),
         scene_writer(models=[mesh_model(bounds={"min": [-1e308, -1e308, -1e308], "max": [1e308, 1e308, 1e308]})])),
     2, ["scene.json", "/models/0/density/bounds"], desc="max - min overflows to infinity")
case("wrong-ok-voxelize-bounds-nan", "wrong-ok",
     ["voxelize", "m.obj", "-r", "8", "--bounds", "nan", "0", "0", "1", "1", "1", "-o", "v.vdb"],
     raw_writer("m.obj", TRIANGLE_OBJ), 2, ["--bounds"], must_not_exist=["v.vdb", "*.tmp-*"])
case("wrong-ok-voxelize-bounds-empty", "wrong-ok",
     ["voxelize", "m.obj", "-r", "8", "--bounds", "0", "0", "0", "0", "0", "0", "-o", "v.vdb"],
     raw_writer("m.obj", TRIANGLE_OBJ), 2, ["--bounds"], must_not_exist=["v.vdb", "*.tmp-*"])
case("wrong-ok-output-nothing", "wrong-ok", ["bake", "scene.json", "-o", "out"],
     scene_writer(output={"vdb": False, "lbh": False}), 2, ["scene.json", "/output"], must_not_exist=OUT_GONE)

# ---------------------------------------------------------------------------------------- trust


def _manifest_file(side, value, key="file"):
    def setup(ctx):
        ctx.bake("a")
        ctx.bake("b")
        ctx.edit_manifest(side, lambda m: m["models"][0].__setitem__(key, value))
    return setup


def _abs_path_setup(ctx):
    ctx.bake("a")
    ctx.bake("b")
    ctx.edit_manifest("b", lambda m: m["models"][0].__setitem__("file", ctx.p("a/m.vdb")))


TRUST_FORBID = [PASSWD_LEAK]
LEADS_OUT = ("outside", "symlink", "link")   # the refusal says why: it leads out of the folder
for nm, side, value in [("other-etc-passwd", "b", "../../../../etc/passwd"),
                        ("reference-etc-passwd", "a", "../../../../etc/passwd"),
                        ("other-dev-zero", "b", "/dev/zero"),
                        ("other-dotdot", "b", ".."), ("other-dot", "b", "."), ("other-empty", "b", ""),
                        ("other-subpath", "b", "./../b/m.vdb"), ("other-nul", "b", "m.vdb\u0000../../etc/passwd")]:
    case("trust-compare-file-%s" % nm, "trust", ["compare", "a", "b"], _manifest_file(side, value), 2,
         ["manifest.json", "/models/0/file"], forbid=TRUST_FORBID, timeout=HANG_T, max_seconds=5)
case("trust-compare-file-backslashes", "trust", ["compare", "a", "b"], _manifest_file("b", "..\\..\\etc\\passwd"), 2,
     [], forbid=TRUST_FORBID, desc="backslashes are plain characters on POSIX: a missing file inside the folder")
case("trust-compare-file-absolute", "trust", ["compare", "a", "b"], _abs_path_setup, 2,
     ["manifest.json", "/models/0/file"], desc="an absolute path to a real bake file elsewhere")


def _symlinked_vdb(target):
    def setup(ctx):
        ctx.bake("a")
        ctx.bake("b")
        os.remove(ctx.p("b/m.vdb"))
        ctx.symlink(target, "b/m.vdb")
    return setup


for nm, target in [("to-other-bake", "../a/m.vdb"), ("to-etc-passwd", "/etc/passwd"), ("to-dev-zero", "/dev/zero"),
                   ("absolute-to-other-bake", None)]:
    setup = _symlinked_vdb(target) if target else (
        lambda ctx: (_symlinked_vdb("/nonexistent")(ctx), ctx.symlink(ctx.p("a/m.vdb"), "b/m.vdb")))
    case("trust-compare-symlink-%s" % nm, "trust", ["compare", "a", "b"], setup, 2, ["m.vdb", LEADS_OUT], forbid=TRUST_FORBID,
         timeout=HANG_T, max_seconds=5, desc="the output folder's m.vdb is a symlink leading outside it")
case("trust-compare-file-is-subfolder-entry", "trust", ["compare", "a", "b"],
     lambda ctx: (_manifest_file("b", "sub/m.vdb")(ctx), ctx.mkdir("b/sub"), shutil.copy(ctx.p("b/m.vdb"), ctx.p("b/sub/m.vdb"))),
     2, ["manifest.json", "/models/0/file"])
case("trust-compare-file-is-number", "trust", ["compare", "a", "b"], _manifest_file("b", 5), 2,
     ["manifest.json", "/models/0/file"])
case("trust-compare-file-is-100k-chars", "trust", ["compare", "a", "b"], _manifest_file("b", "x" * 100_000 + ".vdb"), 2,
     ["manifest.json", "/models/0/file"], max_output_bytes=64 << 10)
case("trust-compare-manifest-symlink-passwd", "trust", ["compare", "a", "b"],
     lambda ctx: (ctx.bake("a"), ctx.bake("b"), ctx.symlink("/etc/passwd", "b/manifest.json")), 2, ["manifest.json"],
     forbid=TRUST_FORBID)
case("trust-compare-solution-file-outside", "trust", ["compare", "a", "b"],
     lambda ctx: (ctx.bake("a"), ctx.bake("b"),
                  ctx.edit_manifest("b", lambda m: m["models"][0]["solutions"][0].__setitem__("file", "../../../../etc/passwd"))),
     (0, 2), [], forbid=TRUST_FORBID, desc="compare reads the model's file; a solution's file entry must not be read")
for nm, key, value in [("etc-passwd", "file", "../../../../etc/passwd"), ("dev-zero", "file", "/dev/zero"),
                       ("absolute", "file", "/etc/passwd"), ("lbh-outside", "lbh_file", "../../x.lbh")]:
    case("trust-inspect-%s-%s" % (key.replace("_", "-"), nm), "trust", ["inspect", "b"], _manifest_file("b", value, key),
         2, ["manifest.json", "/models/0/" + key], forbid=TRUST_FORBID, timeout=HANG_T, max_seconds=5)
case("trust-inspect-manifest-json-directly", "trust", ["inspect", "b/manifest.json"],
     _manifest_file("b", "../../../../etc/passwd"), 2, ["manifest.json", "/models/0/file"], forbid=TRUST_FORBID)
case("trust-inspect-symlink-outside", "trust", ["inspect", "b"], _symlinked_vdb("/etc/passwd"), 2, ["m.vdb", LEADS_OUT],
     forbid=TRUST_FORBID)
case("trust-inspect-manifest-symlink-passwd", "trust", ["inspect", "b"],
     lambda ctx: (ctx.bake("b"), ctx.symlink("/etc/passwd", "b/manifest.json")), 2, ["manifest.json"],
     forbid=TRUST_FORBID)
case("trust-inspect-json-passwd-symlink", "trust", ["inspect", "x.json"],
     lambda ctx: ctx.symlink("/etc/passwd", "x.json"), 2, ["x.json"], forbid=TRUST_FORBID,
     desc="a .json that is not JSON: the error must not quote the file's content")
case("trust-bake-scene-is-passwd", "trust", ["validate", "--no-timing", "x.json"],
     lambda ctx: ctx.symlink("/etc/passwd", "x.json"), 2, ["x.json"], forbid=TRUST_FORBID)

# -------------------------------------------------------------------------------------- message

for nm, sc, ptr in [
        ("models-number", scene_obj(models=5), "/models"),
        ("models-entry-number", scene_obj(models=[5]), "/models/0"),
        ("density-array", scene_obj(models=[{"name": "m", "density": [], "material": "cloud"}]), "/models/0/density"),
        ("density-type-number", scene_obj(models=[{"name": "m", "density": {"type": 5}, "material": "cloud"}]),
         "/models/0/density/type"),
        ("name-number", scene_obj(models=[dict(box_model(), name=5)]), "/models/0/name"),
        ("resolution-string", scene_obj(models=[box_model(res="8")]), "/models/0/density/resolution"),
        ("resolution-negative", scene_obj(models=[box_model(res=-8)]), "/models/0/density/resolution"),
        ("resolution-1e20", scene_obj(models=[box_model(res=1e20)]), "/models/0/density/resolution"),
        ("material-number", scene_obj(models=[box_model(material=7)]), "/models/0/material"),
        ("material-g-two-values", scene_obj(models=[box_model(material={"preset": "cloud", "g": [0.1, 0.2]})]),
         "/models/0/material/g"),
        ("material-sigma-string", scene_obj(models=[box_model(material={"sigma_a": "0.1", "sigma_s": 0.5, "g": 0})]),
         "/models/0/material/sigma_a"),
        ("lighting-string", scene_obj(lighting="base"), "/lighting"),
        ("solutions-object", scene_obj(lighting={"mode": "base", "solutions": {"a": 1}}), "/lighting/solutions"),
        ("sun-elevation-string", scene_obj(lighting={"mode": "static", "sun": {"elevation": "60", "azimuth": 0}}),
         "/lighting/sun/elevation"),
        ("iterations-bool", scene_obj(solver={"iterations": True}), "/solver/iterations"),
        ("tolerance-string", scene_obj(solver={"tolerance": "1e-4"}), "/solver/tolerance"),
        ("output-lbh-string", scene_obj(output={"lbh": "yes"}), "/output/lbh"),
        ("seed-2p53-plus-1", scene_obj(models=[dict(box_model(), density=dict(box_model()["density"], seed=2**53 + 1))]),
         "/models/0/density/seed"),
        ("seed-2p64", scene_obj(models=[dict(box_model(), density=dict(box_model()["density"], seed=2**64))]),
         "/models/0/density/seed"),
        ("seed-negative", scene_obj(models=[dict(box_model(), density=dict(box_model()["density"], seed=-1))]),
         "/models/0/density/seed"),
        ("margin-zero", scene_obj(models=[box_model(margin=0)]), "/models/0/margin"),
        ("margin-float", scene_obj(models=[box_model(margin=1.5)]), "/models/0/margin"),
        ("name-slash", scene_obj(models=[box_model(name="../evil")]), "/models/0/name"),
        ("name-nul", scene_obj(models=[box_model(name="a\u0000b")]), "/models/0/name"),
        ("names-duplicate", scene_obj(models=[box_model("m"), box_model("m")]), "/models/1/name"),
        ("unknown-field", scene_obj(models=[dict(box_model(), resolutoin=8)]), "resolutoin"),
        ("version-2", scene_obj(version=2), "/version"),
        ("procedural-size-tiny", scene_obj(models=[dict(box_model(), density=dict(box_model()["density"], size=1e-300))]),
         "/models/0/density/size"),
]:
    case("message-json-%s" % nm, "message", ["validate", "--no-timing", "scene.json"],
         (lambda s: lambda ctx: ctx.json("scene.json", s))(sc), 2, ["scene.json", ptr],
         desc="scene JSON type/range error: names file and JSON pointer")

for nm, text, frags in [
        ("top-level-array", "[]", []), ("empty-file", "", []), ("trailing-comma", '{"version": 1,}', []),
        ("number-1e400", json.dumps(scene_obj()).replace('"resolution": 8', '"resolution": 1e400'), ["resolution"]),
        ("duplicate-key", '{"version": 1, "version": 1, "models": []}', ["version"]),
        ("invalid-utf8", b'{"version": 1, "name": "\xff\xfe", "models": []}', []),
        ("lone-surrogate", '{"version": 1, "name": "\\ud800", "models": []}', []),
        ("binary-garbage", bytes(random.Random(3).randrange(256) for _ in range(4096)), []),
        ("nesting-100-in-comment", json.dumps(scene_obj())[:-1] + ', "comment": ' + "[" * 100 + "]" * 100 + "}",
         [("nest", "deep", "depth")]),
        ("nan-literal", json.dumps(scene_obj()).replace('"density_scale": 0.5', '"density_scale": NaN'), []),
]:
    case("message-scene-%s" % nm, "message", ["validate", "--no-timing", "scene.json"],
         (lambda t: lambda ctx: ctx.write("scene.json", t))(text), 2, ["scene.json"] + frags,
         max_output_bytes=64 << 10, desc="malformed scene: no raw parser message")
case("message-scene-missing", "message", ["bake", "nope.json", "-o", "out"], None, 2, ["nope.json"],
     must_not_exist=OUT_GONE)
case("message-vdb-missing", "message", ["validate", "--no-timing", "scene.json"],
     scene_writer(models=[vdb_model(path="nope.vdb")]), 2, ["nope.vdb", "/models/0/density"])
case("message-mesh-missing", "message", ["validate", "--no-timing", "scene.json"],
     scene_writer(models=[mesh_model(path="nope.obj")]), 2, ["nope.obj", "/models/0/density"])
case("message-vdb-not-vdb", "message", ["validate", "--no-timing", "scene.json"],
     seq(raw_writer("d.vdb", "this is text\n"), scene_writer(models=[vdb_model()])), 2, ["d.vdb"])
case("message-vdb-grid-not-found", "message", ["validate", "--no-timing", "scene.json"],
     lambda ctx: (ctx.small_vdb("d.vdb"), ctx.scene(models=[vdb_model(grid="dens1ty")])), 2, ["d.vdb", "dens1ty"])
case("message-json-vdb-grid-empty-name", "message", ["validate", "--no-timing", "scene.json"],
     lambda ctx: (ctx.small_vdb("d.vdb"), ctx.scene(models=[vdb_model(grid="")])), 2,
     ["scene.json", "/models/0/density"])
case("message-vdb-grid-is-B00", "message", ["validate", "--no-timing", "scene.json"],
     lambda ctx: (ctx.small_vdb("d.vdb"), ctx.scene(models=[vdb_model(grid="B00")])), 2, ["d.vdb", "B00"])
case("message-vdb-unnamed-density-grid", "message", ["validate", "--no-timing", "scene.json"],
     lambda ctx: (ctx.write_vdb("d.vdb", [ctx.float_grid(box_voxels(0, 0, 0), name="")]), ctx.scene(models=[vdb_model()])),
     2, [VDB_NAMED, "density"], needs_vdb=True, desc="the file's only grid has an empty name")
case("message-inspect-unnamed-grids", "message", ["inspect", "d.vdb"],
     lambda ctx: ctx.write_vdb("d.vdb", [ctx.float_grid([(0, 0, 0)], name=""), ctx.vec3_grid([(0, 0, 0)], name="")]),
     0, ["d.vdb", "vec3s"], needs_vdb=True)
case("message-compress-unnamed-vec3-grid", "message", ["compress", "d.vdb", "--threshold", "0"],
     lambda ctx: ctx.write_vdb("d.vdb", [ctx.vec3_grid(box_voxels(0, 0, 0), name="")]), 2, ["d.vdb", "name"],
     needs_vdb=True, must_not_exist=["d.lbh", "*.tmp-*"],
     desc="a Vec3f grid with an empty name: .lbh names are 1..15 printable characters")
case("message-compress-long-grid-name", "message", ["compress", "d.vdb", "--threshold", "0"],
     lambda ctx: ctx.write_vdb("d.vdb", [ctx.vec3_grid(box_voxels(0, 0, 0), name="B00_with_a_long_name")]), 2,
     ["d.vdb", "B00_with_a_long_name"], needs_vdb=True, must_not_exist=["d.lbh", "*.tmp-*"],
     desc="20 characters do not fit the 15 of an .lbh solution name: refuse, do not truncate")
case("message-compress-non-ascii-grid-name", "message", ["compress", "d.vdb", "--threshold", "0"],
     lambda ctx: ctx.write_vdb("d.vdb", [ctx.vec3_grid(box_voxels(0, 0, 0), name="B\u00e9\n")]), 2,
     ["d.vdb", "name"], needs_vdb=True, must_not_exist=["d.lbh", "*.tmp-*"])
case("message-inspect-empty-grid-bbox", "message", ["inspect", "d.vdb"],
     lambda ctx: ctx.write_vdb("d.vdb", [ctx.float_grid([(0, 0, 0)]), ctx.float_grid([], name="brown")]), 0,
     ["brown"], needs_vdb=True, forbid=[r"2147483647", r"-2147483648"],
     desc="an empty grid's bounding box is shown as empty, not as [2147483647..-2147483648]")
case("message-validate-json-to-dev-full", "message", ["validate", "--json", "--no-timing", "scene.json"],
     scene_writer(), 1, [], stdout_file="/dev/full", desc="validate --json > /dev/full must not exit 0")
case("message-inspect-json-to-dev-full", "message", ["inspect", "ref", "--json"], lambda ctx: ctx.bake("ref"), 1, [],
     stdout_file="/dev/full")
case("message-compare-to-dev-full", "message", ["compare", "a", "b"], lambda ctx: (ctx.bake("a"), ctx.bake("b")), 1,
     [], stdout_file="/dev/full", desc="a comparison whose result cannot be printed must not look like a pass")
case("message-voxelize-json-to-dev-full", "message", ["voxelize", "m.obj", "-r", "8", "--json", "-o", "v.vdb"],
     raw_writer("m.obj", TRIANGLE_OBJ), 1, [], stdout_file="/dev/full")
case("message-vdb-negative-extent-never-printed", "message", ["validate", "--no-timing", "scene.json"],
     _far_voxels([(INT32_MIN + 10, 0, 0), (INT32_MAX - 10, 0, 0)]), (1, 2), [("far.vdb", "/models/0/density")], needs_vdb=True, timeout=30,
     max_seconds=10, forbid=[r"spans\s+-", r"-\d+\s*x\s*\d+"],
     desc="an extent of 2^32-20 nodes: never printed as a negative size")
case("message-manifest-models-number", "message", ["inspect", "ref"],
     lambda ctx: (ctx.bake("ref"), ctx.edit_manifest("ref", lambda m: m.__setitem__("models", 5))), 2,
     ["manifest.json", "/models"])
case("message-manifest-truncated", "message", ["compare", "a", "b"],
     lambda ctx: (ctx.bake("a"), ctx.bake("b"), ctx.write("b/manifest.json", ctx.read("b/manifest.json")[:200])), 2,
     ["manifest.json"])
case("message-manifest-lattice-missing", "message", ["compare", "a", "b"],
     lambda ctx: (ctx.bake("a"), ctx.bake("b"), ctx.edit_manifest("b", lambda m: m["models"][0].pop("lattice"))), 2,
     ["manifest.json", "lattice"])
case("message-manifest-solutions-string", "message", ["compare", "a", "b"],
     lambda ctx: (ctx.bake("a"), ctx.bake("b"), ctx.edit_manifest("a", lambda m: m["models"][0].__setitem__("solutions", "all"))),
     2, ["manifest.json", "/models/0/solutions"])
case("message-cli-unknown-subcommand", "message", ["frobnicate"], None, 2, ["frobnicate"])
case("message-cli-missing-scene", "message", ["bake"], None, 2, ["scene"])
case("message-cli-threads-negative", "message", ["bake", "scene.json", "--threads", "-1"], scene_writer(), 2,
     ["--threads"], must_not_exist=["scene-bake"])
case("message-cli-tolerance-nan", "message", ["bake", "scene.json", "--tolerance", "nan", "-o", "out"], scene_writer(),
     2, ["--tolerance"], must_not_exist=OUT_GONE)
case("message-cli-compress-threshold-inf", "message", ["compress", "d.vdb", "--threshold", "inf"],
     lambda ctx: ctx.small_vdb("d.vdb"), 2, ["--threshold"], must_not_exist=["d.lbh"])
case("message-cli-bench-size-7", "message", ["bench", "--size", "7"], None, 2, ["--size"])
case("message-cli-voxelize-bounds-count", "message", ["voxelize", "m.obj", "--bounds", "0", "0", "0", "1", "1"],
     raw_writer("m.obj", TRIANGLE_OBJ), 2, ["--bounds"], must_not_exist=["m.vdb", "*.tmp-*"])
for how in ["truncated-1", "truncated-header", "bad-header-crc", "bad-section-crc", "big-endian", "version-3",
            "file-bytes-huge", "solutions-4096", "index-min-overflow", "matrix-nan", "matrix-singular",
            "masks-offset-past-end", "name-unterminated", "direction-not-index"]:
    case("message-lbh-%s" % how, "message", ["inspect", "m.lbh"], (lambda h: lambda ctx: lbh_variant(ctx, "m.lbh", h))(how),
         2, ["m.lbh"], timeout=HANG_T, max_seconds=5, desc="damaged .lbh (%s): input error naming the file" % how)
for how in ["truncated-1", "index-min-overflow", "name-unterminated", "direction-not-index"]:
    case("message-decompress-lbh-%s" % how, "message", ["decompress", "m.lbh", "-o", "x.vdb"],
         (lambda h: lambda ctx: lbh_variant(ctx, "m.lbh", h))(how), 2, ["m.lbh"], timeout=HANG_T, max_seconds=5,
         must_not_exist=["x.vdb", "*.tmp-*"])


# ------------------------------------------------------------------------------------ injection
# Every value that enters a generated script (lblight submit's sbatch scripts): a control character
# is refused before anything is written; anything else is quoted so that bash and sbatch's own
# #SBATCH parser read back exactly the value given, and nothing runs that the user did not name.

SUBMIT = ["submit", "scene.json", "--slurm", "--dry-run", "--no-timing"]


def _sbatch_arguments(line):
    """The arguments sbatch reads from one '#SBATCH ...' line (its _get_argument: quotes '...' or
    "...", a backslash escapes the next character also inside quotes, an unquoted '#' ends)."""
    rest, out = line[len("#SBATCH"):], []
    i = 0
    while i < len(rest):
        while i < len(rest) and rest[i].isspace():
            i += 1
        if i >= len(rest):
            break
        arg, quote, esc = "", None, False
        while i < len(rest) and (quote or not rest[i].isspace()):
            c = rest[i]
            i += 1
            if esc:
                esc = False
            elif c == "\\":
                esc = True
                continue
            elif quote:
                if c == quote:
                    quote = None
                    continue
            elif c in "\"'":
                quote = c
                continue
            elif c == "#":
                return out + ([arg] if arg else [])
            arg += c
        if quote:
            return None  # sbatch: "Unmatched quote", fatal
        out.append(arg)
    return out


def _check_script_reads_back(expected):
    """expected: {option: value} that the units script's #SBATCH lines must carry exactly."""
    def check(ctx, res):
        path = ctx.p("run/slurm/units.sbatch")
        if not os.path.exists(path):
            return "no units.sbatch written"
        text = open(path, encoding="utf-8", errors="replace").read()
        if subprocess.run(["bash", "-n", path], capture_output=True).returncode != 0:
            return "units.sbatch is not valid bash"
        got = {}
        for line in text.splitlines():
            if line.startswith("#SBATCH"):
                args = _sbatch_arguments(line)
                if args is None:
                    return "sbatch could not parse: %r" % line
                for a in args:
                    k, _, v = a.partition("=")
                    got.setdefault(k, []).append(v)
            elif line.startswith("#") or not line.strip():
                continue
        for k, v in expected.items():
            if v not in got.get(k, []):
                return "%s reads back as %r, not %r" % (k, got.get(k), v)
        return None
    return check


def _run_units_script(ctx, res):
    """Runs the array script of a dry run with a stand-in lblight that records its arguments: every
    argument arrives as one word, and nothing else runs."""
    if res.returncode != 0:
        return "exit %d" % res.returncode
    env = dict(os.environ, SLURM_ARRAY_TASK_ID="0", SLURM_ARRAY_JOB_ID="7", SLURM_CPUS_PER_TASK="1")
    subprocess.run(["bash", ctx.p("run/slurm/units.sbatch")], cwd=ctx.dir, env=env, capture_output=True, timeout=30)
    if any(os.path.exists(ctx.p(n)) for n in ("pwned", "run/pwned")):
        return "the script ran a command hidden in a value"
    rec = ctx.p("args.txt")
    if not os.path.exists(rec):
        return "the stand-in lblight did not run"
    args = open(rec).read().split("\0")[:-1]
    if args[:2] != ["bake", ctx.p("scene.json")] or "--only" not in args:
        return "the stand-in got %r" % args
    return None


def _fake_lblight(ctx):
    ctx.scene()
    path = ctx.write("bin $(touch pwned) 'x/lblight", "#!/bin/sh\nprintf '%s\\0' \"$@\" > \"$(dirname \"$0\")/../args.txt\"\n")
    os.chmod(path, 0o755)


for opt in ("--partition", "--account", "--time", "--mem", "--sbatch-arg"):
    case("injection-newline-%s" % opt.strip("-"), "injection", SUBMIT + ["-o", "run", opt + "=p\ntouch pwned"],
         scene_writer(), 2, [opt, "control character"], must_not_exist=["run", "pwned"], max_seconds=10,
         desc="a newline in %s would end the #SBATCH line and start a command" % opt)
case("injection-newline-output", "injection", SUBMIT + ["-o", "run\ntouch pwned"], scene_writer(), 2,
     ["-o", "control character"], must_not_exist=["run*", "pwned"], max_seconds=10)
case("injection-cr-partition", "injection", SUBMIT + ["-o", "run", "--partition", "p\rq"], scene_writer(), 2,
     ["--partition", "control character"], must_not_exist=["run"])
case("injection-escape-account", "injection", SUBMIT + ["-o", "run", "--account", "a\x1b[31mred"], scene_writer(), 2,
     ["--account", "\\x1b"], must_not_exist=["run"], desc="refused, and the escape sequence shown escaped")
case("injection-quoted-values-read-back", "injection",
     SUBMIT + ["-o", "run", "--partition", "p q$(touch pwned)'\"#x", "--account", "a\\b",
               "--sbatch-arg=--comment=two words # not a comment"],
     scene_writer(), 0, [], must_not_exist=["pwned"],
     check=_check_script_reads_back({"--partition": "p q$(touch pwned)'\"#x", "--account": "a\\b",
                                     "--comment": "two words # not a comment"}),
     desc="spaces, quotes, $( ), backslashes and '#' reach sbatch as the values given")
case("injection-folder-with-spaces-and-percent", "injection", SUBMIT + ["-o", "my run %j $(touch pwned)"],
     scene_writer(), 0, [], must_not_exist=["pwned"],
     check=lambda ctx, res: (lambda t: None if "--output=\"" in t and "%%j" in t else "output pattern not quoted: " + t)(
         open(ctx.p("my run %j $(touch pwned)/slurm/units.sbatch")).read()),
     desc="the log pattern keeps the folder's '%' literal (%%) and its spaces quoted")
case("injection-script-runs-as-named", "injection",
     SUBMIT + ["-o", "run", "--lblight", "bin $(touch pwned) 'x/lblight"], _fake_lblight, 0, [],
     must_not_exist=["pwned", "run/pwned"], check=_run_units_script,
     desc="the array script, run with bash, passes the odd executable path and scene as single words")
case("injection-printed-command-quoted", "injection", SUBMIT + ["-o", "a b;touch pwned"], scene_writer(), 0,
     ["'"], must_not_exist=["pwned"],
     check=lambda ctx, res: None if "sbatch --parsable --array=0 '" in res.text() else
     "the printed sbatch command leaves the path unquoted",
     desc="the 'submit by hand' commands quote the scripts' paths")

# ------------------------------------------------------------------------------------ overwrite
# Outputs that are FIFOs or devices are refused up front (no hang, nothing left), and no output may
# replace an input of the same run or another of its outputs.

for name, args, setup in [
        ("relight", ["relight", "ref", "-o", "f.vdb"], lambda ctx: ctx.bake("ref")),
        ("schema", ["schema", "-o", "f.vdb"], None),
        ("render-exr", ["render", "ref", "--size", "8x8", "-o", "f.vdb"], lambda ctx: ctx.bake("ref")),
        ("render-png", ["render", "ref", "--size", "8x8", "-o", "p.exr", "--png", "f.vdb"], lambda ctx: ctx.bake("ref")),
        ("voxelize", ["voxelize", "m.obj", "-r", "8", "-o", "f.vdb"], raw_writer("m.obj", TRIANGLE_OBJ)),
        ("compress", ["compress", "d.vdb", "--threshold", "0", "-o", "f.vdb"], lambda ctx: ctx.small_vdb("d.vdb")),
        ("decompress", ["decompress", "m.lbh", "-o", "f.vdb"], lambda ctx: ctx.small_lbh("m.lbh"))]:
    if name == "compress":
        args = args[:-1] + ["f.lbh"]
    fifo_name = args[-1]
    case("overwrite-output-fifo-" + name, "overwrite", args,
         (lambda st, fn: lambda ctx: ((st or (lambda c: None))(ctx), ctx.fifo(fn)))(setup, fifo_name),
         2, [fifo_name, NOT_REGULAR], timeout=HANG_T, max_seconds=5, must_not_exist=["p.exr", "p.png", "*.tmp-*"],
         desc="an output that is a FIFO would block until a reader comes: refused before any work")
case("overwrite-render-png-dev-full", "overwrite",
     ["render", "ref", "--size", "8x8", "-o", "p.exr", "--png", "/dev/full"], lambda ctx: ctx.bake("ref"), 2,
     ["/dev/full", NOT_REGULAR], must_not_exist=["p.exr", "*.tmp-*"], desc="no .exr left when the preview cannot be written")
case("overwrite-schema-dev-null", "overwrite", ["schema", "-o", "/dev/null"], None, 2, ["/dev/null", NOT_REGULAR])
case("overwrite-relight-into-bake", "overwrite", ["relight", "ref", "-o", "ref/light.vdb"], lambda ctx: ctx.bake("ref"),
     2, ["ref", "inside"], must_not_exist=["ref/light.vdb"], unchanged=["ref/manifest.json", "ref/m.vdb"],
     desc="a relit file inside the bake it reads would make the bake a folder with a foreign file")
case("overwrite-relight-own-input", "overwrite", ["relight", "ref/m.vdb", "-o", "ref/m.vdb"],
     lambda ctx: ctx.bake("ref"), 2, ["ref/m.vdb"], unchanged=["ref/m.vdb"])
case("overwrite-relight-manifest", "overwrite", ["relight", "ref", "-o", "ref/manifest.vdb"],
     lambda ctx: ctx.bake("ref"), 2, ["manifest.vdb"], unchanged=["ref/manifest.json"])
case("overwrite-relight-json-name", "overwrite", ["relight", "ref", "-o", "same.json"], lambda ctx: ctx.bake("ref"),
     2, ["same.json", ".vdb"], must_not_exist=["same.json"])
case("overwrite-relight-hard-link", "overwrite", ["relight", "ref", "--model", "m", "-o", "h.vdb"],
     lambda ctx: (ctx.bake("ref"), os.link(ctx.p("ref/m.vdb"), ctx.p("h.vdb"))), 2, ["h.vdb"],
     unchanged=["ref/m.vdb"], desc="a hard link to the input is the input")
case("overwrite-merge-into-part", "overwrite", ["merge", "ref", "-o", "ref"], lambda ctx: ctx.bake("ref"), 2,
     ["ref"], unchanged=["ref/manifest.json", "ref/m.vdb"])
case("overwrite-merge-into-part-spelled-otherwise", "overwrite", ["merge", "ref", "-o", "./x/../ref/"],
     lambda ctx: ctx.bake("ref"), 2, ["ref"], unchanged=["ref/manifest.json", "ref/m.vdb"])
case("overwrite-bake-over-own-density", "overwrite", ["bake", "scene.json", "-o", "ref"],
     lambda ctx: (ctx.bake("ref"), ctx.scene(models=[vdb_model(path="ref/m.vdb")])), 2, ["ref"],
     unchanged=["ref/m.vdb", "ref/manifest.json"], desc="the bake would replace the folder holding its own input")
case("overwrite-bake-folder-holds-scene", "overwrite", ["bake", "out/scene.json", "-o", "out"],
     lambda ctx: ctx.scene("out/scene.json"), 2, ["out"], unchanged=["out/scene.json"])
case("overwrite-compress-hard-link", "overwrite", ["compress", "d.vdb", "--threshold", "0", "-o", "h.lbh"],
     lambda ctx: (ctx.small_vdb("d.vdb"), os.link(ctx.p("d.vdb"), ctx.p("h.lbh"))), 2, ["h.lbh"], unchanged=["d.vdb"])
case("overwrite-render-into-bake", "overwrite", ["render", "ref", "--size", "8x8", "-o", "ref/p.exr"],
     lambda ctx: ctx.bake("ref"), 2, ["ref"], must_not_exist=["ref/p.exr", "ref/p.png"])
case("overwrite-render-exr-is-png", "overwrite", ["render", "ref", "--size", "8x8", "-o", "p.exr", "--png", "./p.exr"],
     lambda ctx: ctx.bake("ref"), 2, ["p.exr"], must_not_exist=["p.exr"])
case("overwrite-schema-unwritable-folder", "overwrite", ["schema", "-o", "ro/s.json"],
     lambda ctx: (os.makedirs(ctx.p("ro")), os.chmod(ctx.p("ro"), 0o555)), 2, ["ro", "writ"], run_as_nobody=True,
     must_not_exist=["ro/s.json"])


# ----------------------------------------------------------------------------------------------
# Running

class Result:
    def __init__(self):
        self.returncode = None
        self.stdout = b""
        self.stderr = b""
        self.elapsed = 0.0
        self.hung = False
        self.after_signal = None
        self.output_bytes = 0

    def text(self):
        return (self.stdout + b"\n" + self.stderr).decode("utf-8", "replace")

    def first_message_line(self):
        lines = [l.strip() for l in self.stderr.decode("utf-8", "replace").splitlines() if l.strip()]
        for pat in (r"^(\[[^\]]*\]\s*)?(error|fatal)\s*:", r"\b(error|fatal)\s*:"):
            for l in lines:
                if re.search(pat, l, re.I):
                    return l
        for l in lines:
            if " info: " not in l and " warning: " not in l:
                return l
        out = [l.strip() for l in self.stdout.decode("utf-8", "replace").splitlines() if l.strip()]
        return (out or lines or [""])[0]


def _reader(stream, sink, cap=8 << 20):
    total = 0
    while True:
        chunk = stream.read(65536)
        if not chunk:
            break
        total += len(chunk)
        if sum(len(c) for c in sink) < cap:
            sink.append(chunk)
    sink.append(None)
    sink.append(total)


def execute(runner, c, ctx):
    res = Result()
    cmd = [runner.exe] + c["args"]
    stdout_target = subprocess.PIPE
    out_file = None
    if c.get("stdout_file"):
        out_file = open(c["stdout_file"], "wb")
        stdout_target = out_file
    stdin = subprocess.PIPE if c.get("stdin") == "open-pipe" else subprocess.DEVNULL
    timeout = c.get("timeout", runner.timeout)
    t0 = time.monotonic()
    proc = subprocess.Popen(limited(cmd, c.get("run_as_nobody") and os.geteuid() == 0), cwd=ctx.dir, stdin=stdin,
                            stdout=stdout_target, stderr=subprocess.PIPE,
                            start_new_session=True, env=child_env())
    if out_file:
        out_file.close()
    sinks = {}
    threads = []
    for nm, stream in (("stdout", proc.stdout), ("stderr", proc.stderr)):
        if stream is None:
            continue
        sinks[nm] = []
        t = threading.Thread(target=_reader, args=(stream, sinks[nm]), daemon=True)
        t.start()
        threads.append(t)

    def wait_until(deadline):
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            try:
                proc.wait(timeout=min(left, 0.05))
                return True
            except subprocess.TimeoutExpired:
                pass

    hard_deadline = t0 + timeout
    last_signal = None
    at = t0
    for delay, sig in c.get("signals", []):
        at = at + delay
        if wait_until(min(at, hard_deadline)):
            break
        if time.monotonic() >= hard_deadline:
            break
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            break
        last_signal = time.monotonic()
        at = last_signal
    if proc.returncode is None and not wait_until(hard_deadline):
        res.hung = True
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait()
    end = time.monotonic()
    if proc.stdin:
        proc.stdin.close()
    for t in threads:
        t.join(timeout=5)
    res.returncode = proc.returncode
    res.elapsed = end - t0
    if last_signal is not None:
        res.after_signal = end - last_signal
    for nm, sink in sinks.items():
        data = b"".join(x for x in sink if isinstance(x, bytes))
        total = sink[-1] if sink and isinstance(sink[-1], int) else len(data)
        res.output_bytes += total
        setattr(res, nm, data)
    # anything still in the process group (a leaked child) is ended too
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    return res


def walk_rel(root):
    out = []
    for dp, dns, fns in os.walk(root):
        for n in dns + fns:
            out.append(os.path.relpath(os.path.join(dp, n), root).replace(os.sep, "/"))
    return out


def digest(path):
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return None
    if stat.S_ISREG(st.st_mode):
        with open(path, "rb") as f:
            return ("file", zlib.crc32(f.read()), st.st_size)
    if stat.S_ISLNK(st.st_mode):
        return ("link", os.readlink(path))
    return ("other", stat.S_IFMT(st.st_mode))


def sig_name(n):
    try:
        return signal.Signals(n).name
    except ValueError:
        return "signal %d" % n


def judge(runner, c, ctx, res, before):
    reasons = []
    rc = res.returncode
    expect = c["expect_exit"]
    allowed = tuple(expect) if isinstance(expect, (list, tuple)) else (expect,)
    if res.hung:
        return "HANG", ["HANG: still running after %.0f s (process group killed)" % c.get("timeout", runner.timeout)]
    verdict = "FAIL"
    if rc is not None and rc < 0:
        sent = [s for _, s in c.get("signals", [])]
        if -rc in sent:
            reasons.append("killed by %s it was sent (no handler; expected exit %s)" % (sig_name(-rc), "/".join(map(str, allowed))))
        else:
            verdict = "CRASH"
            reasons.append("CRASH: %s%s" % (sig_name(-rc), " (file size limit)" if -rc == signal.SIGXFSZ else ""))
    elif rc not in allowed:
        reasons.append("exit %s, expected %s" % (rc, "/".join(map(str, allowed))))
    text = res.text()
    low = text.lower()
    for frag in c["expect"]:
        alts = frag if isinstance(frag, tuple) else (frag,)
        if not any(a.lower() in low for a in alts):
            reasons.append("message lacks %s" % (" or ".join(repr(a) for a in alts)))
    for pat in DEFAULT_FORBID + list(c.get("forbid", [])):
        m = re.search(pat, text, re.I)
        if m:
            reasons.append("output shows %r" % m.group(0)[:60])
    limit = c.get("max_output_bytes", 4 << 20)
    if res.output_bytes > limit:
        reasons.append("printed %d bytes (limit %d)" % (res.output_bytes, limit))
    if c.get("max_seconds") is not None and res.elapsed > c["max_seconds"]:
        reasons.append("took %.1f s (limit %.0f s)" % (res.elapsed, c["max_seconds"]))
    if c.get("max_seconds_after_signal") is not None and res.after_signal is not None \
            and res.after_signal > c["max_seconds_after_signal"]:
        reasons.append("ran %.1f s after the last signal (limit %.0f s)" % (res.after_signal, c["max_seconds_after_signal"]))
    if c.get("signals") and res.after_signal is None and not res.hung:
        reasons.append("ended after %.1f s, before any signal was sent (the case needs a longer-running command)"
                       % res.elapsed)
    present = walk_rel(ctx.dir)
    pats = list(c.get("must_not_exist", []))
    if c.get("default_must_not_exist", True):
        pats += [p for p in DEFAULT_MUST_NOT_EXIST if p not in pats]
    # the case's own patterns count whatever matches (a planted stale staging folder must go); the
    # default ones only what the run created
    left = sorted({p for p in present for pat in pats if fnmatch.fnmatchcase(p, pat)
                   and (pat in c.get("must_not_exist", []) or p not in before["files"])})
    if left:
        reasons.append("left behind: %s" % ", ".join(left[:5]))
    for pat in c.get("must_exist", []):
        if not any(fnmatch.fnmatchcase(p, pat) for p in present):
            reasons.append("missing: %s" % pat)
    for rel, d in before["unchanged"].items():
        now = digest(ctx.p(rel))
        if now != d:
            reasons.append("%s was %s" % (rel, "removed" if now is None else "changed"))
    if c.get("check"):
        try:
            r = c["check"](ctx, res)
        except SetupError as e:
            r = "check could not run: %s" % e
        except Exception as e:  # noqa: BLE001
            r = "check raised %s: %s" % (type(e).__name__, e)
        if r:
            reasons.append(r)
    if not reasons:
        return "PASS", []
    return verdict, reasons


def _make_writable(path):
    for dp, dns, fns in os.walk(path):
        for n in dns:
            try:
                p = os.path.join(dp, n)
                if not os.path.islink(p):
                    os.chmod(p, 0o755)
            except OSError:
                pass


def rmtree(path):
    _make_writable(path)
    shutil.rmtree(path, ignore_errors=True)


class Runner:
    def __init__(self, exe, src, root, timeout, keep):
        self.exe = exe
        self.src = src
        self.root = root
        self.timeout = timeout
        self.keep = keep
        self._bake = None
        self._lbh = None
        self._lock = threading.RLock()

    def cached_bake(self):
        with self._lock:
            return self._cached_bake()

    def cached_lbh(self):
        with self._lock:
            return self._cached_lbh()

    def _cached_bake(self):
        if self._bake is None:
            d = os.path.join(self.root, "_shared")
            os.makedirs(d, exist_ok=True)
            with open(os.path.join(d, "small.json"), "w") as f:
                json.dump(scene_obj(name="small"), f)
            p = subprocess.run(limited([self.exe, "-q", "bake", "small.json", "-o", "bake"]), cwd=d,
                               stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=child_env(),
                               timeout=120)
            if p.returncode != 0:
                raise SetupError("the shared small bake failed (exit %d): %s"
                                 % (p.returncode, p.stderr.decode("utf-8", "replace").strip()[-300:]))
            self._bake = os.path.join(d, "bake")
        return self._bake

    def _cached_lbh(self):
        if self._lbh is None:
            b = self.cached_bake()
            d = os.path.dirname(b)
            p = subprocess.run(limited([self.exe, "-q", "compress", "bake/m.vdb", "--threshold", "0.01", "--relative",
                                        "-o", "m.lbh"]), cwd=d, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, env=child_env(), timeout=120)
            if p.returncode != 0:
                raise SetupError("the shared compress failed (exit %d)" % p.returncode)
            self._lbh = os.path.join(d, "m.lbh")
        return self._lbh

    def run_case(self, c):
        folder = os.path.join(self.root, c["name"])
        os.makedirs(folder)
        if c.get("run_as_nobody") and os.geteuid() == 0:
            for p in (self.root, folder):
                os.chmod(p, 0o755)
            exe_ok = all(os.stat(d).st_mode & 0o001 for d in _parents(self.exe)) and os.stat(self.exe).st_mode & 0o005 == 0o005
            if not exe_ok:
                return "SKIP", ["the executable is not readable by user nobody (needed to test a read-only folder as root)"], None
        ctx = Ctx(self, folder)
        try:
            if c.get("needs_vdb"):
                ctx.need_vdb()
            c["setup"](ctx)
        except SkipCase as e:
            return "SKIP", [str(e)], None
        except subprocess.TimeoutExpired as e:
            return "FAIL", ["setup timed out: %s" % e], None
        except SetupError as e:
            return "FAIL", ["setup: %s" % e], None
        except Exception as e:  # noqa: BLE001 (a generator bug must not stop the corpus)
            return "FAIL", ["setup raised %s: %s" % (type(e).__name__, e)], None
        if c.get("run_as_nobody") and os.geteuid() == 0:
            for dp, dns, fns in os.walk(folder):
                for n in fns:
                    p = os.path.join(dp, n)
                    if not os.path.islink(p):
                        os.chmod(p, os.stat(p).st_mode | 0o044)
        before = {"files": set(walk_rel(folder)),
                  "unchanged": {rel: digest(ctx.p(rel)) for rel in c.get("unchanged", [])}}
        res = execute(self, c, ctx)
        verdict, reasons = judge(self, c, ctx, res, before)
        return verdict, reasons, res


def _parents(path):
    path = os.path.abspath(path)
    out = []
    while True:
        path = os.path.dirname(path)
        out.append(path)
        if path == os.path.dirname(path):
            return out


def main(argv=None):
    ap = argparse.ArgumentParser(description="Run lblight's hostile-input corpus (tests/hostile/README.md).")
    ap.add_argument("exe", help="the lblight executable")
    ap.add_argument("source_dir", help="the source tree (for reference; cases generate their own inputs)")
    ap.add_argument("--only", action="append", default=[], help="run only cases whose name contains this (repeatable)")
    ap.add_argument("--class", dest="classes", action="append", default=[], choices=CLASSES,
                    help="run only cases of this class (repeatable)")
    ap.add_argument("--list", action="store_true", help="list the cases and exit")
    ap.add_argument("--keep", metavar="DIR", help="create the case folders under DIR and keep them")
    ap.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT, help="default seconds per case (60)")
    ap.add_argument("-j", "--jobs", type=int, default=min(4, os.cpu_count() or 1),
                    help="cases run side by side (default: 4, or the number of CPUs when fewer)")
    ap.add_argument("-v", "--verbose", action="store_true", help="also show exit code and message of passing cases")
    a = ap.parse_args(argv)

    cases = [c for c in CASES if (not a.only or any(s in c["name"] for s in a.only))
             and (not a.classes or c["class"] in a.classes)]
    if a.list:
        for c in cases:
            ex = c["expect_exit"]
            ex = "/".join(map(str, ex)) if isinstance(ex, (list, tuple)) else str(ex)
            print("%-52s %-14s exit %-6s lblight %s%s" % (c["name"], c["class"], ex, " ".join(c["args"]),
                                                         ("  # " + c["desc"]) if c.get("desc") else ""))
        print("%d case(s)" % len(cases))
        return 0
    exe = os.path.abspath(a.exe)
    if not (os.path.isfile(exe) and os.access(exe, os.X_OK)):
        print("run_corpus.py: %s is not an executable file" % a.exe, file=sys.stderr)
        return 2
    if a.keep:
        os.makedirs(a.keep, exist_ok=True)
        root = tempfile.mkdtemp(prefix="lblight-hostile-", dir=os.path.abspath(a.keep))
    else:
        root = tempfile.mkdtemp(prefix="lblight-hostile-", dir="/tmp")
    runner = Runner(exe, os.path.abspath(a.source_dir), root, a.timeout, a.keep)
    if vdb is None:
        print("note: pyopenvdb is not available (Debian python3-openvdb, %s): the .vdb-crafting cases are skipped"
              % SYSTEM_PYTHON)
    counts = {}
    failed = []
    t_start = time.monotonic()
    print_lock = threading.Lock()

    def one(c):
        try:
            verdict, reasons, res = runner.run_case(c)
        except Exception as e:  # noqa: BLE001 (a harness bug in one case must not stop the others)
            verdict, reasons, res = "FAIL", ["harness error %s: %s" % (type(e).__name__, e)], None
        with print_lock:
            report(c, verdict, reasons, res)
        if not a.keep:
            rmtree(os.path.join(root, c["name"]))

    def report(c, verdict, reasons, res):
        counts[verdict] = counts.get(verdict, 0) + 1
        if verdict == "PASS":
            extra = ""
            if a.verbose:
                extra = " [exit %s: %s]" % (res.returncode, res.first_message_line()[:200])
            print("PASS  %-14s %s (%.1f s)%s" % (c["class"], c["name"], res.elapsed, extra), flush=True)
        elif verdict == "SKIP":
            print("SKIP  %-14s %s: %s" % (c["class"], c["name"], "; ".join(reasons)), flush=True)
        else:
            obs = ""
            if res is not None:
                obs = " [exit %s, %.1f s: %s]" % (res.returncode, res.elapsed, res.first_message_line()[:200])
            print("%-5s %-14s %s: %s%s" % (verdict, c["class"], c["name"], "; ".join(reasons), obs), flush=True)
            failed.append((c, verdict))

    try:
        if a.jobs <= 1:
            for c in cases:
                one(c)
        else:
            from concurrent.futures import ThreadPoolExecutor
            with ThreadPoolExecutor(max_workers=a.jobs) as pool:
                list(pool.map(one, cases))
    finally:
        if not a.keep:
            rmtree(root)
    total = sum(counts.values())
    print("\n%d case(s) in %.0f s: %d passed, %d failed (%d crash, %d hang), %d skipped"
          % (total, time.monotonic() - t_start, counts.get("PASS", 0),
             counts.get("FAIL", 0) + counts.get("CRASH", 0) + counts.get("HANG", 0), counts.get("CRASH", 0),
             counts.get("HANG", 0), counts.get("SKIP", 0)))
    by_class = {}
    for c, v in failed:
        by_class.setdefault(c["class"], []).append(c["name"])
    for cls in CLASSES:
        if cls in by_class:
            print("  %s: %s" % (cls, ", ".join(by_class[cls])))
    if a.keep:
        print("case folders kept in %s" % root)
    return 1 if failed else 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except BrokenPipeError:   # output piped into head & co.
        sys.exit(1)
