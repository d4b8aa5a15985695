// Writes a glTF file with its PNG and JPEG images re-encoded as KTX2 / Basis Universal
// (KHR_texture_basisu): `node encode.mjs IN.gltf OUT.glb etc1s|uastc` (ETC1S in BasisLZ, or
// UASTC in Zstandard). Needs npm ktx2-encoder, @gltf-transform/core and /extensions, pngjs and
// jpeg-js; the images' texels are read as stored, without colour management.
import { NodeIO } from "@gltf-transform/core";
import { ALL_EXTENSIONS } from "@gltf-transform/extensions";
import { ktx2 } from "ktx2-encoder/gltf-transform";
import { PNG } from "pngjs";
import jpeg from "jpeg-js";
const [, , input, output, mode] = process.argv;
const io = new NodeIO().registerExtensions(ALL_EXTENSIONS);
const doc = await io.read(input);
const imageDecoder = async (buffer) => {
  if (buffer[0] === 0xff) {
    const j = jpeg.decode(Buffer.from(buffer), { useTArray: true, formatAsRGBA: true });
    return { data: new Uint8Array(j.data), width: j.width, height: j.height };
  }
  const png = PNG.sync.read(Buffer.from(buffer));
  return { data: new Uint8Array(png.data), width: png.width, height: png.height };
};
await doc.transform(
  ktx2({
    isUASTC: mode === "uastc",
    needSupercompression: mode === "uastc",
    generateMipmap: false,
    imageDecoder,
  }),
);
await io.write(output, doc);
