#!/usr/bin/env python3
"""Writes tests/gltf/BoxTextured-instanced/: Khronos's BoxTextured (CC BY 4.0) drawn by
nine nodes that share its one mesh (rotated, scaled unevenly, one mirrored), as one GLB.
`gltf-transform instance` then makes the EXT_mesh_gpu_instancing twin (see LICENSE.md)."""
import json, math, struct, sys
from pathlib import Path

root = Path(__file__).resolve().parent.parent
src = root / "tests/gltf/BoxTextured"
out = root / "tests/gltf/BoxTextured-instanced/BoxTextured-instanced.glb"
doc = json.loads((src / "BoxTextured.gltf").read_text())
bin_data = (src / doc["buffers"][0]["uri"]).read_bytes()
image = (src / doc["images"][0]["uri"]).read_bytes()

# The image goes into the binary chunk after the geometry (4-byte aligned).
pad = lambda b: b + b"\0" * (-len(b) % 4)
geometry = pad(bin_data)
doc["bufferViews"].append(
    {"buffer": 0, "byteOffset": len(geometry), "byteLength": len(image)}
)
doc["images"] = [{"bufferView": len(doc["bufferViews"]) - 1, "mimeType": "image/png"}]
blob = pad(geometry + image)
doc["buffers"] = [{"byteLength": len(blob)}]

def quat(axis, degrees):
    a = math.radians(degrees) / 2
    n = math.sqrt(sum(c * c for c in axis))
    return [c / n * math.sin(a) for c in axis] + [math.cos(a)]

nodes = []
for k in range(9):
    x, z = k % 3 - 1, k // 3 - 1
    node = {"mesh": 0, "translation": [1.6 * x, 0.1 * k, 1.6 * z]}
    node["rotation"] = quat([0.3, 1.0, 0.2 * x], 20.0 * k)
    node["scale"] = [0.5 + 0.1 * k, 0.6, 0.5 + 0.05 * (8 - k)]
    if k == 4:
        node["scale"][0] = -node["scale"][0]  # mirrored
    nodes.append(node)
doc["nodes"] = [{"name": "grid", "children": list(range(1, 10))}] + nodes
doc["scenes"] = [{"nodes": [0]}]
doc["asset"]["generator"] = "termtrace scripts/instanced-gltf.py"

text = pad(json.dumps(doc, separators=(",", ":")).encode()).replace(b"\0", b" ")
chunks = struct.pack("<I4s", len(text), b"JSON") + text
chunks += struct.pack("<I4s", len(blob), b"BIN\0") + blob
out.write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks)
print(out, out.stat().st_size, "bytes", file=sys.stderr)
