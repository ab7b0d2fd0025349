"""What an OpenVDB file holds, read from its header in plain Python (no pyopenvdb, no bpy): the
file-level metadata and each grid's name, type and metadata. The add-on uses it to tell an lblight
bake, a relit volume (`lblight relight`) and anything else apart before it creates a datablock, so
a wrong file is an error naming it, not a half-imported object.

Layout (OpenVDB io/Archive.cc, io/File.cc, GridDescriptor.cc, MetaMap.cc; little-endian): int64
magic 0x56444220, uint32 file version, [>= 211] uint32 library major and minor, [>= 212] char
has-grid-offsets, [220..221] char compressed, uuid (36 ASCII characters from 218 on, 16 bytes
before); the file's MetaMap; int32 grid count and one descriptor per grid (unique name, type,
[>= 216] instance parent, int64 grid, block and end positions); at the grid position [>= 222]
uint32 compression flags, then the grid's MetaMap. A MetaMap is uint32 count, then per entry name
and type (uint32 length + bytes) and the value (uint32 size + bytes)."""
import struct

MAGIC = 0x56444220


class VdbError(ValueError):
    """Not a readable OpenVDB file (the message says why, without the path)."""


class _Reader:
    def __init__(self, f, size):
        self.f, self.size = f, size

    def take(self, n, what):
        if n < 0 or self.f.tell() + n > self.size:
            raise VdbError(f"cut short or not an OpenVDB file: {what} runs past the end of the file")
        return self.f.read(n)

    def unpack(self, fmt, what):
        return struct.unpack("<" + fmt, self.take(struct.calcsize("<" + fmt), what))

    def string(self, what, limit=1 << 20):
        (n,) = self.unpack("I", what)
        if n > limit:
            raise VdbError(f"not an OpenVDB file: {what} claims {n} bytes")
        return self.take(n, what).decode("utf-8", "replace")


_SCALARS = {"bool": "?", "int32": "i", "int64": "q", "float": "f", "double": "d"}
_VECTORS = {"vec2i": "2i", "vec2s": "2f", "vec2d": "2d", "vec3i": "3i", "vec3s": "3f", "vec3d": "3d"}


def _value(type_name, raw):
    if type_name == "string":
        return raw.decode("utf-8", "replace")
    fmt = _SCALARS.get(type_name) or _VECTORS.get(type_name)
    if fmt is None or struct.calcsize("<" + fmt) != len(raw):
        return raw  # a type the add-on does not need: kept as bytes
    v = struct.unpack("<" + fmt, raw)
    return v[0] if type_name in _SCALARS else tuple(v)


def _metamap(r, what):
    (count,) = r.unpack("I", what + " count")
    if count > 100000:
        raise VdbError(f"not an OpenVDB file: {what} claims {count} entries")
    meta = {}
    for _ in range(count):
        name = r.string(what + " name")
        type_name = r.string(what + " type")
        (n,) = r.unpack("I", f"{what} '{name}' size")
        meta[name] = _value(type_name, r.take(n, f"{what} '{name}'"))
    return meta


def read(path):
    """{'version': file version, 'metadata': {..}, 'grids': [{'name', 'type', 'metadata'}]}.
    Raises OSError when the file cannot be opened, VdbError when it is not a whole OpenVDB file."""
    with open(path, "rb") as f:
        f.seek(0, 2)
        size = f.tell()
        f.seek(0)
        r = _Reader(f, size)
        if size < 8 or r.unpack("q", "magic")[0] != MAGIC:
            raise VdbError("not an OpenVDB file (no VDB magic number at its start)")
        (version,) = r.unpack("I", "file version")
        if version >= 211:
            r.unpack("II", "library version")
        has_offsets = True
        if version >= 212:
            has_offsets = r.unpack("b", "grid offsets flag")[0] != 0
        if 220 <= version < 222:
            r.unpack("b", "compression flag")
        r.take(36 if version >= 218 else 16, "uuid")
        info = {"version": version, "metadata": _metamap(r, "file metadata"), "grids": []}
        if not has_offsets:
            return info  # an old stream without descriptors: grid names unknown
        (count,) = r.unpack("i", "grid count")
        if count < 0 or count > 100000:
            raise VdbError(f"not an OpenVDB file: it claims {count} grids")
        for _ in range(count):
            unique = r.string("grid name")
            gtype = r.string("grid type")
            if version >= 216:
                r.string("instance parent")
            grid_pos, _block_pos, end_pos = r.unpack("qqq", "grid offsets")
            if not (0 < grid_pos <= end_pos <= size):
                raise VdbError(f"cut short: grid '{unique}' runs past the end of the file")
            f.seek(grid_pos)
            if version >= 222:
                r.unpack("I", "grid compression")
            gmeta = _metamap(r, f"grid '{unique}' metadata")
            f.seek(end_pos)
            info["grids"].append({"name": unique.split("\x1e")[0], "type": gtype.replace("_HalfFloat", ""),
                                  "metadata": gmeta})
        return info
