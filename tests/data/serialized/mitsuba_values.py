"""Loads each fixture shape with Mitsuba 3 (scalar_rgb) and writes fixtures/mitsuba_values.json."""
import json, os, subprocess, sys

CASES = [("two_shapes_v3.serialized", 0), ("two_shapes_v3.serialized", 1), ("two_shapes_v3.serialized", 2),
         ("two_shapes_v3.serialized", 3), ("normals_uvs_v4.serialized", 0), ("normals_uvs_v4.serialized", 1),
         ("normals_uvs_v4.serialized", 2), ("no_dictionary_v4.serialized", 0), ("no_dictionary_v4.serialized", 1)]

CHILD = r'''
import json, sys, mitsuba as mi
mi.set_variant("scalar_rgb")
mesh = mi.load_dict({"type": "serialized", "filename": sys.argv[1], "shape_index": int(sys.argv[2])})
p = mi.traverse(mesh)
out = {"mitsuba_version": mi.__version__}
for key in ["vertex_positions", "vertex_normals", "vertex_texcoords", "faces"]:
    out[key] = [float(x) if key != "faces" else int(x) for x in p[key]] if key in p else None
out["has_vertex_normals"] = bool(mesh.has_vertex_normals())
print(json.dumps(out))
'''

results = []
for file, index in CASES:
    r = subprocess.run([sys.executable, "-c", CHILD, "fixtures/" + file, str(index)], capture_output=True, text=True)
    entry = {"file": file, "shape_index": index}
    if r.returncode == 0:
        entry["mitsuba"] = json.loads(r.stdout.strip().splitlines()[-1])
    else:
        entry["mitsuba"] = {"error": (r.stderr.strip().splitlines() or ["exit %d" % r.returncode])[-1][:300],
                            "returncode": r.returncode}
    results.append(entry)
    print(file, index, json.dumps(entry["mitsuba"])[:300])
for e in results:
    if "error" in e["mitsuba"]:
        e["mitsuba"]["error"] = e["mitsuba"]["error"].replace(os.path.abspath("fixtures") + "/", "")
open("fixtures/mitsuba_values.json", "w").write(json.dumps(results, separators=(",", ":")).replace("},{\"file\"", "},\n{\"file\"") + "\n")
