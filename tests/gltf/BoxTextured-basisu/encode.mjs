// Writes BoxTextured with its PNG re-encoded as KTX2 / Basis Universal (ETC1S or UASTC).
import { NodeIO } from "@gltf-transform/core";
import { ALL_EXTENSIONS } from "@gltf-transform/extensions";
import { ktx2 } from "ktx2-encoder/gltf-transform";
import { PNG } from "pngjs";
const [,, input, output, mode] = process.argv;
const io = new NodeIO().registerExtensions(ALL_EXTENSIONS);
const doc = await io.read(input);
const imageDecoder = async (buffer) => {
  const png = PNG.sync.read(Buffer.from(buffer));
  return { data: new Uint8Array(png.data), width: png.width, height: png.height };
};
await doc.transform(ktx2({ isUASTC: mode === "uastc", needSupercompression: mode === "uastc", generateMipmap: false, imageDecoder }));
await io.write(output, doc);
