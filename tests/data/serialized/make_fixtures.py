"""Writes small Mitsuba `serialized` fixture files with an independent writer (zlib + struct)."""
import struct, zlib, os

HAS_NORMALS, HAS_UVS, HAS_COLORS, FACE_NORMALS, SINGLE, DOUBLE = 0x1, 0x2, 0x8, 0x10, 0x1000, 0x2000


def shape_stream(version, positions, indices, normals=None, uvs=None, colors=None,
                 double=False, face_normals=False, name="shape"):
    flags = DOUBLE if double else SINGLE
    if normals is not None: flags |= HAS_NORMALS
    if uvs is not None: flags |= HAS_UVS
    if colors is not None: flags |= HAS_COLORS
    if face_normals: flags |= FACE_NORMALS
    fmt = "<%dd" if double else "<%df"
    body = struct.pack("<I", flags)
    if version == 4:
        body += name.encode() + b"\0"
    body += struct.pack("<QQ", len(positions), len(indices))
    for arr in (positions, normals, uvs, colors):
        if arr is not None:
            flat = [x for v in arr for x in v]
            body += struct.pack(fmt % len(flat), *flat)
    flat = [i for t in indices for i in t]
    body += struct.pack("<%dI" % len(flat), *flat)
    return struct.pack("<HH", 0x041C, version) + zlib.compress(body, 9)


def write(path, version, shapes, dictionary=True):
    out, offsets = b"", []
    for s in shapes:
        offsets.append(len(out))
        out += shape_stream(version, **s)
    if dictionary:
        out += b"".join(struct.pack("<I" if version == 3 else "<Q", o) for o in offsets)
        out += struct.pack("<I", len(shapes))
    with open(path, "wb") as f:
        f.write(out)
    return len(out)


n = (1 / 3, 2 / 3, 2 / 3)
square = dict(positions=[(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], indices=[(0, 1, 2), (0, 2, 3)])
tri_uv = dict(positions=[(0.1, 0.2, 0.3), (2.5, -1.25, 0.0), (0.0, 3.0, -4.0)], indices=[(2, 0, 1)],
              uvs=[(0.0, 0.0), (1.0, 0.0), (0.25, 0.75)])
quad_dp = dict(positions=[(0.1, 0.2, 0.3), (1.1, 0.2, 0.3), (1.1, 1.2, 0.3), (0.1, 1.2, 0.3000000001)],
               indices=[(0, 1, 2), (2, 3, 0)], normals=[n, n, (0.0, 0.0, 1.0), (0.6, 0.0, 0.8)],
               uvs=[(0, 0), (1, 0), (1, 1), (0, 1)], colors=[(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1)],
               double=True, name="quad_double")
faceted = dict(positions=[(0, 0, 1), (1, 0, 1), (0, 1, 1)], indices=[(0, 1, 2)],
               normals=[(0, 0, 1)] * 3, uvs=[(0.5, 0.5)] * 3, face_normals=True, name="faceted")

os.makedirs("fixtures", exist_ok=True)
for name, version, shapes, dictionary in [
    ("two_shapes_v3.serialized", 3, [square, tri_uv], True),
    ("normals_uvs_v4.serialized", 4, [quad_dp, faceted], True),
    ("no_dictionary_v4.serialized", 4, [dict(tri_uv, normals=[(0, 0, 1), (0, 1, 0), (1, 0, 0)], name="t")], False),
]:
    print(name, write("fixtures/" + name, version, shapes, dictionary), "bytes")
