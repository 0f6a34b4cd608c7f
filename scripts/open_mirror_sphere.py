#!/usr/bin/env python3
"""Writes the glass sphere of the open-mirror bench scene
(bench/scenes/open-mirror/meshes/unit_sphere.ply): a unit icosphere, the icosahedron
subdivided SUBDIVISIONS times with every vertex projected onto the sphere, smooth normals
(the vertex positions), outward winding. Binary little-endian PLY as the shared scenes use
(float x y z nx ny nz; list uint8 int vertex_indices). Deterministic: the same bytes every
run. The scene places and scales it with its to_world, so Mitsuba and arpa read the same
triangles.

    python3 scripts/open_mirror_sphere.py [OUT.ply]
"""
import math
import struct
import sys
from pathlib import Path

SUBDIVISIONS = 4


def icosphere(subdivisions):
    t = (1.0 + math.sqrt(5.0)) / 2.0
    verts = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
             (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8),
             (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]

    def unit(v):
        n = math.sqrt(sum(c * c for c in v))
        return tuple(c / n for c in v)

    verts = [unit(v) for v in verts]
    for _ in range(subdivisions):
        cache = {}

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                cache[key] = len(verts)
                verts.append(unit(tuple((verts[a][i] + verts[b][i]) / 2.0 for i in range(3))))
            return cache[key]

        new = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new
    return verts, faces


def main():
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent.parent / "bench/scenes/open-mirror/meshes/unit_sphere.ply"
    verts, faces = icosphere(SUBDIVISIONS)
    # Outward winding: the face normal points away from the centre.
    for a, b, c in faces:
        p = [verts[i] for i in (a, b, c)]
        e1 = [p[1][i] - p[0][i] for i in range(3)]
        e2 = [p[2][i] - p[0][i] for i in range(3)]
        n = (e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0])
        assert sum(n[i] * (p[0][i] + p[1][i] + p[2][i]) for i in range(3)) > 0.0, "inward face"
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment open-mirror glass sphere: unit icosphere, "
        f"{SUBDIVISIONS} subdivisions (scripts/open_mirror_sphere.py)\n"
        f"element vertex {len(verts)}\nproperty float x\nproperty float y\nproperty float z\n"
        "property float nx\nproperty float ny\nproperty float nz\n"
        f"element face {len(faces)}\nproperty list uint8 int vertex_indices\nend_header\n"
    )
    body = bytearray(header.encode("ascii"))
    for v in verts:
        body += struct.pack("<6f", *v, *v)
    for f in faces:
        body += struct.pack("<B3i", 3, *f)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_bytes(bytes(body))
    print(f"wrote {out}: {len(verts)} vertices, {len(faces)} triangles")


if __name__ == "__main__":
    main()
