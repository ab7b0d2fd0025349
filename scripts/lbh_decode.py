#!/usr/bin/env python3
"""Independent .lbh decoder, written from docs/lbh-format.md alone (standard library only).

    lbh_decode.py FILE.lbh                         validate and summarise
    lbh_decode.py FILE.lbh --sample X Y Z [...]    JSON: samples (index space) of every solution
    lbh_decode.py FILE.lbh --dump                  JSON: every decoded node of every solution
    lbh_decode.py FILE.lbh --check-vdb OUT.vdb     compare decoded nodes with a .vdb (needs pyopenvdb)

It shares no code with lblight's C++ reader; tests/compress/test_lbh_io.cpp runs it against the reader to
keep the format document honest.
"""
import json
import math
import struct
import sys
import zlib

MAGIC = b"\x89LBH\r\n\x1a\n"


class LbhError(Exception):
    pass


def f32(x):
    """Round a Python float to binary32 (the format's arithmetic is f32)."""
    return struct.unpack("<f", struct.pack("<f", x))[0]


def blocks_for(n):
    return 1 if n <= 1 else (n - 1 + 2) // 3


def align64(v):
    return (v + 63) // 64 * 64


class Stream:
    def __init__(self, data):
        self.data = data
        self._validate()

    def _validate(self):
        d = self.data
        if len(d) < 8 or d[:8] != MAGIC:
            raise LbhError("not an .lbh file")
        if len(d) < 256:
            raise LbhError("truncated")
        version, tag, hb, eb, file_bytes, count, flags = struct.unpack_from("<IIIIQII", d, 8)
        if tag != 0x01020304:
            raise LbhError("bad endianness tag")
        if version not in (1, 2):
            raise LbhError("unsupported version %d" % version)
        if hb != 256 or eb != 128 or flags != 0:
            raise LbhError("bad header sizes or flags")
        if file_bytes != len(d):
            raise LbhError("file is %d bytes, header says %d" % (len(d), file_bytes))
        if zlib.crc32(d[:252]) != struct.unpack_from("<I", d, 252)[0]:
            raise LbhError("header CRC mismatch")
        self.dims = struct.unpack_from("<3i", d, 40)
        self.index_min = struct.unpack_from("<3i", d, 52)
        self.blocks = struct.unpack_from("<3I", d, 64)
        for n, b in zip(self.dims, self.blocks):
            if not 1 <= n <= 1 << 20 or b != blocks_for(n):
                raise LbhError("bad dims / blocks")
        self.index_to_world = struct.unpack_from("<16d", d, 80)
        table_offset, table_crc = struct.unpack_from("<QI", d, 208)
        if table_offset != 256 or not 1 <= count <= 4096 or 256 + 128 * count > len(d):
            raise LbhError("bad table")
        if zlib.crc32(d[256:256 + 128 * count]) != table_crc:
            raise LbhError("table CRC mismatch")
        nblocks = self.blocks[0] * self.blocks[1] * self.blocks[2]
        pos = 256 + 128 * count
        self.solutions = []
        for s in range(count):
            e = 256 + 128 * s
            name = d[e:e + 16].split(b"\0")[0].decode("ascii")
            index, dx, dy, dz, mode = struct.unpack_from("<iiiiI", d, e + 16)
            t_param, t_abs, max_abs = struct.unpack_from("<3f", d, e + 36)
            bc, cc, mo, oo, co = struct.unpack_from("<5Q", d, e + 48)
            mcrc, ocrc, ccrc = struct.unpack_from("<3I", d, e + 88)
            encoding = struct.unpack_from("<I", d, e + 100)[0]
            fast = struct.unpack_from("<Q", d, e + 104)[0]
            step, dcrc = struct.unpack_from("<fI", d, e + 120)
            if encoding not in (0, 1) or (encoding == 1 and version < 2):
                raise LbhError("solution %d: bad coefficient encoding %d" % (s, encoding))
            q8 = encoding == 1
            if q8 and not (step > 0 and math.isfinite(step) and 127.0 * step <= 3.4028234663852886e38):
                raise LbhError("solution %d: bad quantisation step" % s)
            if not q8 and (step != 0 or dcrc != 0):
                raise LbhError("solution %d: bytes 120..127 must be 0 for f32" % s)
            if bc != nblocks or not bc <= cc <= 64 * bc:
                raise LbhError("solution %d: bad counts" % s)
            # f32: masks, offsets, coefficients; q8: masks, offsets, averages, details (offset implied)
            sections = [(mo, 8 * bc), (oo, 4 * bc), (co, 12 * (bc if q8 else cc))]
            if q8:
                sections.append((None, 3 * (cc - bc)))
            starts = []
            for off, size in sections:
                start = align64(pos)
                if (off is not None and off != start) or start + size > len(d):
                    raise LbhError("solution %d: section not at its canonical offset" % s)
                if any(d[pos:start]):
                    raise LbhError("solution %d: padding not zero" % s)
                starts.append(start)
                pos = start + size
            crcs = [mcrc, ocrc, ccrc] + ([dcrc] if q8 else [])
            for (start, (_, size)), crc in zip(zip(starts, sections), crcs):
                if zlib.crc32(d[start:start + size]) != crc:
                    raise LbhError("solution %d: section CRC mismatch" % s)
            masks = struct.unpack_from("<%dQ" % bc, d, mo)
            offsets = struct.unpack_from("<%dI" % bc, d, oo)
            coeffs = struct.unpack_from("<%df" % (3 * (bc if q8 else cc)), d, co)
            details = struct.unpack_from("<%db" % (3 * (cc - bc)), d, starts[3]) if q8 else None
            if not all(math.isfinite(c) for c in coeffs):
                raise LbhError("solution %d: non-finite coefficient" % s)
            if q8 and -128 in details:
                raise LbhError("solution %d: detail -128" % s)
            running = 0
            for b in range(bc):
                if not masks[b] & 1 or offsets[b] != running:
                    raise LbhError("solution %d: block %d inconsistent" % (s, b))
                running += bin(masks[b]).count("1")
            if running != cc or sum(1 for m in masks if m == 1) != fast:
                raise LbhError("solution %d: counts inconsistent" % s)
            self.solutions.append(dict(name=name, index=index, direction=(dx, dy, dz), mode=mode,
                                       threshold=t_abs, masks=masks, offsets=offsets, coeffs=coeffs,
                                       details=details, step=step))
        if pos != len(d):
            raise LbhError("trailing bytes")

    # --- decoding (docs/lbh-format.md sec. 3.2 and 4) ---
    @staticmethod
    def _inverse_1d(v, i0, stride):
        a, dd, d0, d1 = v[i0], v[i0 + stride], v[i0 + 2 * stride], v[i0 + 3 * stride]
        s0, s1 = f32(a + dd), f32(a - dd)
        v[i0], v[i0 + stride] = f32(s0 + d0), f32(s0 - d0)
        v[i0 + 2 * stride], v[i0 + 3 * stride] = f32(s1 + d1), f32(s1 - d1)

    def decode_block(self, sol, b):
        s = self.solutions[sol]
        mask, first = s["masks"][b], s["offsets"][b]
        out = []
        for ch in range(3):
            v = [0.0] * 64
            k = 0
            for l in range(64):
                if mask >> l & 1:
                    if s["details"] is None:      # f32: k-th kept coefficient at offset + k
                        v[l] = s["coeffs"][3 * (first + k) + ch]
                    elif k == 0:                  # q8: the average of block b at b
                        v[l] = s["coeffs"][3 * b + ch]
                    else:                         # q8: k-th detail at offset - b + k - 1, times the step
                        v[l] = f32(s["step"] * s["details"][3 * (first - b + k - 1) + ch])
                    k += 1
            if mask != 1:
                for i in range(16):          # x
                    self._inverse_1d(v, 4 * i, 1)
                for z in range(4):           # y
                    for x in range(4):
                        self._inverse_1d(v, 16 * z + x, 4)
                for i in range(16):          # z
                    self._inverse_1d(v, i, 16)
            else:
                v = [v[0]] * 64
            out.append(v)
        return out  # [channel][x + 4y + 16z]

    def block_index(self, bx, by, bz):
        return (bz * self.blocks[1] + by) * self.blocks[0] + bx

    def decode_lattice(self, sol):
        nx, ny, nz = self.dims
        cache = {}
        out = [None] * (nx * ny * nz)
        for k in range(nz):
            for j in range(ny):
                for i in range(nx):
                    bl, loc = [], []
                    for n, c in zip(self.dims, (i, j, k)):
                        b = (min(c, n - 2) if n >= 2 else 0) // 3
                        bl.append(b)
                        loc.append(c - 3 * b)
                    b = self.block_index(*bl)
                    if b not in cache:
                        cache = {b: self.decode_block(sol, b)}
                    v = cache[b]
                    l = loc[0] + 4 * loc[1] + 16 * loc[2]
                    out[(k * ny + j) * nx + i] = (v[0][l], v[1][l], v[2][l])
        return out

    def sample_index(self, sol, x, y, z):
        bl, loc, a = [], [], []
        for n, p, lo in zip(self.dims, (x, y, z), self.index_min):
            u = p - lo
            if not u > 0:
                u = 0.0
            u = min(u, n - 1)
            i = min(int(math.floor(u)), max(n - 2, 0))
            bl.append(i // 3)
            loc.append(i - 3 * (i // 3))
            a.append(u - i)
        v = self.decode_block(sol, self.block_index(*bl))
        out = [0.0, 0.0, 0.0]
        for c in range(8):
            w, l = 1.0, 0
            for ax in range(3):
                up = c >> ax & 1
                w *= a[ax] if up else 1.0 - a[ax]
                l += (loc[ax] + up) * (1, 4, 16)[ax]
            for ch in range(3):
                out[ch] += w * v[ch][l]
        return out


def main(argv):
    if len(argv) < 2:
        print(__doc__)
        return 2
    try:
        s = Stream(open(argv[1], "rb").read())
    except (LbhError, OSError, struct.error) as e:
        print("lbh_decode: %s: %s" % (argv[1], e), file=sys.stderr)
        return 1
    if "--sample" in argv:
        vals = [float(v) for v in argv[argv.index("--sample") + 1:]]
        pts = [vals[i:i + 3] for i in range(0, len(vals) - 2, 3)]
        print(json.dumps({sol["name"]: [s.sample_index(k, *p) for p in pts] for k, sol in enumerate(s.solutions)}))
    elif "--dump" in argv:
        print(json.dumps({sol["name"]: [list(v) for v in s.decode_lattice(k)] for k, sol in enumerate(s.solutions)}))
    elif "--check-vdb" in argv:
        import pyopenvdb as vdb  # noqa: only for this mode
        path = argv[argv.index("--check-vdb") + 1]
        grids = {g.name: g for g in vdb.readAll(path)[0]}
        nx, ny, nz = s.dims
        worst = 0.0
        for k, sol in enumerate(s.solutions):
            acc = grids[sol["name"]].getConstAccessor()
            dec = s.decode_lattice(k)
            for kk in range(nz):
                for j in range(ny):
                    for i in range(nx):
                        ref = acc.getValue((i + s.index_min[0], j + s.index_min[1], kk + s.index_min[2]))
                        got = dec[(kk * ny + j) * nx + i]
                        worst = max(worst, max(abs(got[c] - ref[c]) for c in range(3)))
        print("max |python decode - %s| = %g over %d solutions" % (path, worst, len(s.solutions)))
        return 0 if worst <= 1e-5 else 1
    else:
        print("%s: %dx%dx%d nodes, %dx%dx%d sub-blocks, %d solution(s): %s" % (
            argv[1], *s.dims, *s.blocks, len(s.solutions), ", ".join(x["name"] for x in s.solutions)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
