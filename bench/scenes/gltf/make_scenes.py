"""Writes the glTF test set (bench/scenes/gltf/README.md): four small glTF 2.0 scenes and, for
each, its Mitsuba 3 XML twin (the same triangles as PLY files, the same lights in watts at
683 lm/W, the same camera), so that a Mitsuba reference of the twin checks arpa's glTF
loader. Needs numpy: python3 make_scenes.py (run in this directory)."""
import base64, json, math, os, struct, zlib
import numpy as np

LM_PER_W = 683.0


def png(path, rgba):
    """Writes an 8-bit RGBA (or RGB, or grey) PNG from a uint8 array (H, W[, C])."""
    a = np.asarray(rgba, np.uint8)
    if a.ndim == 2:
        a = a[..., None]
    h, w, c = a.shape
    ctype = {1: 0, 3: 2, 4: 6}[c]
    raw = b"".join(b"\x00" + a[j].tobytes() for j in range(h))
    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xffffffff)
    data = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, ctype, 0, 0, 0)) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")
    open(path, "wb").write(data)


def ply(path, pos, nrm, uv, tri):
    """ASCII PLY with normals and Mitsuba texture coordinates (u, 1 - v of glTF's)."""
    with open(path, "w") as f:
        f.write(f"ply\nformat ascii 1.0\nelement vertex {len(pos)}\nproperty float x\nproperty float y\nproperty float z\n"
                "property float nx\nproperty float ny\nproperty float nz\nproperty float u\nproperty float v\n"
                f"element face {len(tri)}\nproperty list uchar int vertex_indices\nend_header\n")
        for p, n, t in zip(pos, nrm, uv):
            f.write(f"{p[0]:.7g} {p[1]:.7g} {p[2]:.7g} {n[0]:.7g} {n[1]:.7g} {n[2]:.7g} {t[0]:.7g} {1 - t[1]:.7g}\n")
        for t in tri:
            f.write(f"3 {t[0]} {t[1]} {t[2]}\n")


def quad(center, u, v, uv_scale=1.0):
    c, u, v = np.array(center, float), np.array(u, float), np.array(v, float)
    pos = np.array([c - u - v, c + u - v, c + u + v, c - u + v])
    n = np.cross(u, v); n /= np.linalg.norm(n)
    nrm = np.array([n] * 4)
    uv = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], float) * uv_scale
    return pos, nrm, uv, np.array([[0, 1, 2], [0, 2, 3]])


def sphere(center, r, nu=48, nv=24):
    pos, nrm, uv = [], [], []
    for j in range(nv + 1):
        th = math.pi * j / nv
        for i in range(nu + 1):
            ph = 2 * math.pi * i / nu
            n = np.array([math.sin(th) * math.cos(ph), math.cos(th), -math.sin(th) * math.sin(ph)])
            pos.append(np.array(center) + r * n); nrm.append(n); uv.append([i / nu, j / nv])
    tri = []
    for j in range(nv):
        for i in range(nu):
            a, b = j * (nu + 1) + i, (j + 1) * (nu + 1) + i
            if j > 0:
                tri.append([a, b, a + 1])
            if j < nv - 1:
                tri.append([a + 1, b, b + 1])
    return np.array(pos), np.array(nrm), np.array(uv, float), np.array(tri)


def cube(half):
    pos, nrm, uv, tri = [], [], [], []
    for axis in range(3):
        for s in (-1, 1):
            n = np.zeros(3); n[axis] = s
            u = np.zeros(3); u[(axis + 1) % 3] = half
            v = np.cross(n, u)
            p, q, t, f = quad(n * half, u, v)
            base = len(pos)
            pos += list(p); nrm += list(q); uv += list(t); tri += list(f + base)
    return np.array(pos), np.array(nrm), np.array(uv), np.array(tri)


class Gltf:
    """A one-buffer glTF document (buffer as a .bin file beside it)."""

    def __init__(self):
        self.doc = {"asset": {"version": "2.0", "generator": "arpa make_scenes.py"}, "scene": 0, "scenes": [{"nodes": []}],
                    "nodes": [], "meshes": [], "materials": [], "accessors": [], "bufferViews": [], "buffers": []}
        self.bin = bytearray()

    def view(self, data, target):
        while len(self.bin) % 4:
            self.bin.append(0)
        self.doc["bufferViews"].append({"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data), "target": target})
        self.bin += data
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, a, kind, ctype, target, minmax=False):
        v = self.view(a.tobytes(), target)
        acc = {"bufferView": v, "componentType": ctype, "count": len(a), "type": kind}
        if minmax:
            acc["min"] = a.min(axis=0).tolist(); acc["max"] = a.max(axis=0).tolist()
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1

    def mesh(self, pos, nrm, uv, tri, material):
        attrs = {"POSITION": self.accessor(pos.astype(np.float32), "VEC3", 5126, 34962, True),
                 "NORMAL": self.accessor(nrm.astype(np.float32), "VEC3", 5126, 34962),
                 "TEXCOORD_0": self.accessor(uv.astype(np.float32), "VEC2", 5126, 34962)}
        ind = self.accessor(tri.astype(np.uint32).reshape(-1), "SCALAR", 5125, 34963)
        self.doc["meshes"].append({"primitives": [{"attributes": attrs, "indices": ind, "material": material}]})
        return len(self.doc["meshes"]) - 1

    def node(self, **kw):
        self.doc["nodes"].append(kw)
        self.doc["scenes"][0]["nodes"].append(len(self.doc["nodes"]) - 1)
        return len(self.doc["nodes"]) - 1

    def write(self, name):
        self.doc["buffers"] = [{"uri": "scene.bin", "byteLength": len(self.bin)}]
        open(os.path.join(name, "scene.bin"), "wb").write(bytes(self.bin))
        json.dump(self.doc, open(os.path.join(name, "scene.gltf"), "w"), indent=1)


CAMERA = dict(origin=(0.0, 2.2, 3.2), target=(0.0, 0.3, 0.0), yfov=45.0)


def camera_node(g):
    o, t = np.array(CAMERA["origin"]), np.array(CAMERA["target"])
    f = t - o; f /= np.linalg.norm(f)
    r = np.cross(f, [0, 1, 0]); r /= np.linalg.norm(r)
    u = np.cross(r, f)
    m = np.identity(4); m[:3, 0] = r; m[:3, 1] = u; m[:3, 2] = -f; m[:3, 3] = o
    g.doc.setdefault("cameras", []).append({"type": "perspective", "perspective": {"yfov": math.radians(CAMERA["yfov"]), "aspectRatio": 1.0, "znear": 0.01}})
    g.node(camera=0, matrix=m.T.reshape(-1).tolist())


def xml(name, body):
    o, t = CAMERA["origin"], CAMERA["target"]
    head = f"""<?xml version="1.0" encoding="utf-8"?>
<!-- The Mitsuba twin of scene.gltf (make_scenes.py): the reference of the glTF test set. -->
<scene version="3.0.0">
    <integrator type="{'volpath' if name == 'masked-quad' else 'path'}"><integer name="max_depth" value="12"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="{CAMERA['yfov']}"/><string name="fov_axis" value="y"/>
        <transform name="to_world"><lookat origin="{o[0]}, {o[1]}, {o[2]}" target="{t[0]}, {t[1]}, {t[2]}" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="4096"/></sampler>
        <film type="hdrfilm"><integer name="width" value="128"/><integer name="height" value="128"/><rfilter type="box"/></film>
    </sensor>
"""
    open(os.path.join(name, "scene.xml"), "w").write(head + body + "</scene>\n")


def floor(g, name, material):
    p = quad((0, 0, 0), (2, 0, 0), (0, 0, -2))
    ply(os.path.join(name, "meshes", "floor.ply"), *p)
    g.node(mesh=g.mesh(*p, material))
    return '    <shape type="ply"><string name="filename" value="meshes/floor.ply"/>\n        <bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf></bsdf></shape>\n'


def grey(g, c=0.5):
    g.doc["materials"].append({"pbrMetallicRoughness": {"baseColorFactor": [c, c, c, 1], "metallicFactor": 0, "roughnessFactor": 1}, "doubleSided": True})
    return len(g.doc["materials"]) - 1


def point_light(g, pos, cd):
    g.doc.setdefault("extensionsUsed", []).append("KHR_lights_punctual")
    g.doc.setdefault("extensions", {}).setdefault("KHR_lights_punctual", {"lights": []})["lights"].append({"type": "point", "intensity": cd})
    g.node(translation=list(pos), extensions={"KHR_lights_punctual": {"light": len(g.doc["extensions"]["KHR_lights_punctual"]["lights"]) - 1}})
    return f'    <emitter type="point"><point name="position" x="{pos[0]}" y="{pos[1]}" z="{pos[2]}"/><rgb name="intensity" value="{cd / LM_PER_W:.9g}"/></emitter>\n'


def setup(name):
    os.makedirs(os.path.join(name, "meshes"), exist_ok=True)
    os.makedirs(os.path.join(name, "reference"), exist_ok=True)
    g = Gltf()
    camera_node(g)
    return g


def textured_quad():
    name = "textured-quad"
    g = setup(name)
    tex = np.zeros((8, 8, 3), np.uint8)
    for j in range(8):
        for i in range(8):
            tex[j, i] = (200, 40, 30) if (i + j) % 2 else (230, 230, 210)
    tex[0, 0] = (30, 60, 200)  # marks the first row's first texel
    png(os.path.join(name, "checker.png"), tex)
    g.doc["images"] = [{"uri": "checker.png"}]
    g.doc["samplers"] = [{"magFilter": 9728, "minFilter": 9728}]
    g.doc["textures"] = [{"source": 0, "sampler": 0}]
    g.doc["materials"].append({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0, "roughnessFactor": 1}, "doubleSided": True})
    p = quad((0, 0, 0), (2, 0, 0), (0, 0, -2))
    ply(os.path.join(name, "meshes", "floor.ply"), *p)
    g.node(mesh=g.mesh(*p, 0))
    body = point_light(g, (0.3, 1.6, 0.4), 400.0)
    body += '    <shape type="ply"><string name="filename" value="meshes/floor.ply"/>\n        <bsdf type="twosided"><bsdf type="diffuse"><texture name="reflectance" type="bitmap"><string name="filename" value="checker.png"/><string name="filter_type" value="nearest"/></texture></bsdf></bsdf></shape>\n'
    g.write(name); xml(name, body)


def masked_quad():
    name = "masked-quad"
    g = setup(name)
    tex = np.zeros((16, 16, 4), np.uint8)
    tex[..., :3] = (220, 200, 60)
    for i in range(16):
        tex[:, i, 3] = 255 if (i // 2) % 2 == 0 else 0  # vertical slats, half open
    png(os.path.join(name, "slats.png"), tex)
    png(os.path.join(name, "slats-rgb.png"), tex[..., :3])
    png(os.path.join(name, "slats-alpha.png"), tex[..., 3])
    g.doc["images"] = [{"uri": "slats.png"}]
    g.doc["samplers"] = [{"magFilter": 9728, "minFilter": 9728}]
    g.doc["textures"] = [{"source": 0, "sampler": 0}]
    g.doc["materials"].append({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0, "roughnessFactor": 1}, "alphaMode": "MASK", "alphaCutoff": 0.5, "doubleSided": True})
    body = floor(g, name, grey(g))
    p = quad((0, 0.6, -0.3), (0.6, 0, 0), (0, 0.5, 0))
    ply(os.path.join(name, "meshes", "slats.ply"), *p)
    g.node(mesh=g.mesh(*p, 0))
    body += point_light(g, (0.2, 1.5, 0.9), 300.0)
    body += ('    <shape type="ply"><string name="filename" value="meshes/slats.ply"/>\n'
             '        <bsdf type="mask"><texture name="opacity" type="bitmap"><string name="filename" value="slats-alpha.png"/><boolean name="raw" value="true"/><string name="filter_type" value="nearest"/></texture>\n'
             '            <bsdf type="twosided"><bsdf type="diffuse"><texture name="reflectance" type="bitmap"><string name="filename" value="slats-rgb.png"/><string name="filter_type" value="nearest"/></texture></bsdf></bsdf></bsdf></shape>\n')
    g.write(name); xml(name, body)


def glass_sphere():
    name = "glass-sphere"
    g = setup(name)
    body = floor(g, name, grey(g))
    g.doc["materials"].append({"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1], "metallicFactor": 0, "roughnessFactor": 0},
                               "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0}, "KHR_materials_ior": {"ior": 1.5}}})
    g.doc.setdefault("extensionsUsed", []).extend(["KHR_materials_transmission", "KHR_materials_ior"])
    p = sphere((0, 0.5, 0), 0.5)
    ply(os.path.join(name, "meshes", "sphere.ply"), *p)
    g.node(mesh=g.mesh(*p, 1))
    cd, outer, inner = 600.0, 30.0, 29.5
    g.doc["extensionsUsed"].append("KHR_lights_punctual")
    g.doc.setdefault("extensions", {})["KHR_lights_punctual"] = {"lights": [{"type": "spot", "intensity": cd, "spot": {"outerConeAngle": math.radians(outer), "innerConeAngle": math.radians(inner)}}]}
    h = math.sqrt(0.5)
    g.node(translation=[0.3, 2.5, 0.2], rotation=[-h, 0, 0, h], extensions={"KHR_lights_punctual": {"light": 0}})
    body += ('    <shape type="ply"><string name="filename" value="meshes/sphere.ply"/>\n'
             '        <bsdf type="dielectric"><float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/></bsdf></shape>\n')
    body += (f'    <emitter type="spot"><transform name="to_world"><lookat origin="0.3, 2.5, 0.2" target="0.3, 0, 0.2" up="0, 0, 1"/></transform>\n'
             f'        <rgb name="intensity" value="{cd / LM_PER_W:.9g}"/><float name="cutoff_angle" value="{outer}"/><float name="beam_width" value="{inner}"/></emitter>\n')
    g.write(name); xml(name, body)


def instanced_mesh():
    name = "instanced-mesh"
    g = setup(name)
    body = floor(g, name, grey(g))
    g.doc["materials"].append({"pbrMetallicRoughness": {"baseColorFactor": [0.7, 0.35, 0.2, 1], "metallicFactor": 0, "roughnessFactor": 1}, "doubleSided": True})
    p = cube(0.25)
    ply(os.path.join(name, "meshes", "cube.ply"), *p)
    mesh = g.mesh(*p, 1)
    placements = [([-0.6, 0.25, 0.0], [0, 0.2588190, 0, 0.9659258], [1, 1, 1]), ([0.6, 0.4, -0.3], [0, -0.3826834, 0, 0.9238795], [1.2, 1.6, 1.2])]
    body += '    <shape type="shapegroup" id="cube"><shape type="ply"><string name="filename" value="meshes/cube.ply"/>\n        <bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.7, 0.35, 0.2"/></bsdf></bsdf></shape></shape>\n'
    for t, q, s in placements:
        g.node(mesh=mesh, translation=t, rotation=q, scale=s)
        x, y, z, w = q
        angle = 2 * math.degrees(math.atan2(math.sqrt(x * x + y * y + z * z), w))
        axis = "0, 1, 0" if y >= 0 else "0, -1, 0"
        body += (f'    <shape type="instance"><ref id="cube"/><transform name="to_world"><scale x="{s[0]}" y="{s[1]}" z="{s[2]}"/>'
                 f'<rotate y="{1 if y >= 0 else -1}" angle="{angle:.7g}"/><translate x="{t[0]}" y="{t[1]}" z="{t[2]}"/></transform></shape>\n')
    body += point_light(g, (0.0, 1.8, 1.0), 500.0)
    g.write(name); xml(name, body)


if __name__ == "__main__":
    textured_quad(); masked_quad(); glass_sphere(); instanced_mesh()
