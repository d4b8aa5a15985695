#!/usr/bin/env python3
"""Writes the 10^6-triangle glTF benchmark asset (BENCHMARKS.md, "glTF at scale").

A rippled height field of N x N quads (N = 708: 1 002 528 triangles) with positions, normals,
texture coordinates and 32-bit indices in one .glb, its base colour map the BoxTextured PNG
committed under tests/gltf/ (CC BY 4.0) repeated 16 times each way. Pure Python (no numpy),
deterministic.

    python3 benches/million.py OUT.glb [N]
"""
import array
import json
import math
import os
import struct
import sys


def main():
    out = sys.argv[1]
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 708
    here = os.path.dirname(os.path.abspath(__file__))
    png = open(os.path.join(here, "..", "tests", "gltf", "BoxTextured", "CesiumLogoFlat.png"), "rb").read()
    size = 10.0
    pos = array.array("f")
    nrm = array.array("f")
    uv = array.array("f")

    def height(x, z):
        return 0.15 * math.sin(3.1 * x) * math.cos(2.3 * z) + 0.05 * math.sin(11.0 * (x + z))

    for j in range(n + 1):
        for i in range(n + 1):
            x = size * (i / n - 0.5)
            z = size * (j / n - 0.5)
            y = height(x, z)
            e = 1e-4
            dx = (height(x + e, z) - height(x - e, z)) / (2 * e)
            dz = (height(x, z + e) - height(x, z - e)) / (2 * e)
            l = math.sqrt(dx * dx + 1 + dz * dz)
            pos.extend((x, y, z))
            nrm.extend((-dx / l, 1 / l, -dz / l))
            uv.extend((16 * i / n, 16 * j / n))
    idx = array.array("I")
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            b, c, d = a + 1, a + n + 1, a + n + 2
            # Counter-clockwise seen from +y.
            idx.extend((a, c, b, b, c, d))
    blobs = [pos.tobytes(), nrm.tobytes(), uv.tobytes(), idx.tobytes(), png]
    views, offset, binary = [], 0, b""
    for blob in blobs:
        views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(blob)})
        pad = (-len(blob)) % 4
        binary += blob + b"\0" * pad
        offset += len(blob) + pad
    count = (n + 1) ** 2
    lo = [min(pos[k::3]) for k in range(3)]
    hi = [max(pos[k::3]) for k in range(3)]
    doc = {
        "asset": {"version": "2.0", "generator": "termtrace benches/million.py"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "field"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2},
                                     "indices": 3, "material": 0}]}],
        "materials": [{"name": "field", "pbrMetallicRoughness": {
            "baseColorTexture": {"index": 0}, "metallicFactor": 0.0, "roughnessFactor": 0.6}}],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"wrapS": 10497, "wrapT": 10497}],
        "images": [{"bufferView": 4, "mimeType": "image/png"}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": count, "type": "VEC3", "min": lo, "max": hi},
            {"bufferView": 1, "componentType": 5126, "count": count, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": count, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5125, "count": len(idx), "type": "SCALAR"},
        ],
        "bufferViews": views,
        "buffers": [{"byteLength": len(binary)}],
    }
    js = json.dumps(doc).encode()
    js += b" " * ((-len(js)) % 4)
    total = 12 + 8 + len(js) + 8 + len(binary)
    with open(out + ".tmp", "wb") as f:
        f.write(struct.pack("<III", 0x46546C67, 2, total))
        f.write(struct.pack("<II", len(js), 0x4E4F534A) + js)
        f.write(struct.pack("<II", len(binary), 0x004E4942) + binary)
    os.replace(out + ".tmp", out)
    print(f"wrote {out}: {len(idx) // 3} triangles, {total / 1e6:.1f} MB")


if __name__ == "__main__":
    main()
