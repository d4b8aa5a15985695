#!/usr/bin/env python3
"""Writes the instancing benchmark's file (BENCHMARKS.md, "Instancing"): a GLB in which
COPIES nodes share one mesh of 2·N² triangles (a rippled N×N grid), on a square grid of
spacing 1.2, each turned about +y. The issue's case is 10 000 copies of a 20 000-triangle
mesh: `benches/instanced-forest.py /tmp/forest.glb 10000 100` (1.1 MB).
`gltf-transform instance IN OUT` makes its EXT_mesh_gpu_instancing twin."""
import json, math, struct, sys

out, copies, n = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
pos = []
for j in range(n + 1):
    for i in range(n + 1):
        x, z = i / n, j / n
        pos += [x - 0.5, 0.3 * math.sin(6 * x) * math.cos(5 * z) + 0.3, z - 0.5]
idx = []
for j in range(n):
    for i in range(n):
        a = j * (n + 1) + i
        b = a + n + 1
        idx += [a, b, a + 1, a + 1, b, b + 1]
blob = struct.pack(f"<{len(pos)}f", *pos) + struct.pack(f"<{len(idx)}I", *idx)
side = math.ceil(math.sqrt(copies))
nodes = []
for k in range(copies):
    a = math.radians(37 * k % 360) / 2
    nodes.append({
        "mesh": 0,
        "translation": [round(1.2 * (k % side), 3), 0, round(1.2 * (k // side), 3)],
        "rotation": [0, round(math.sin(a), 6), 0, round(math.cos(a), 6)],
    })
doc = {
    "asset": {"version": "2.0", "generator": "termtrace benches/instanced-forest.py"},
    "scene": 0,
    "scenes": [{"nodes": list(range(copies))}],
    "nodes": nodes,
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
    "accessors": [
        {"bufferView": 0, "componentType": 5126, "count": len(pos) // 3, "type": "VEC3",
         "min": [min(pos[c::3]) for c in range(3)], "max": [max(pos[c::3]) for c in range(3)]},
        {"bufferView": 1, "componentType": 5125, "count": len(idx), "type": "SCALAR"},
    ],
    "bufferViews": [
        {"buffer": 0, "byteLength": 4 * len(pos)},
        {"buffer": 0, "byteOffset": 4 * len(pos), "byteLength": 4 * len(idx)},
    ],
    "buffers": [{"byteLength": len(blob)}],
}
text = json.dumps(doc, separators=(",", ":")).encode()
text += b" " * (-len(text) % 4)
chunks = struct.pack("<I4s", len(text), b"JSON") + text + struct.pack("<I4s", len(blob), b"BIN\0") + blob
open(out, "wb").write(struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks)
print(out, 12 + len(chunks), "bytes", file=sys.stderr)
