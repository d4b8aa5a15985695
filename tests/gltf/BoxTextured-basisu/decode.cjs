// Decodes the KTX2 image of a .glb with Basis Universal's own C++ transcoder (the WebAssembly
// build three.js ships) to an RGBA8 PNG: the independent reading a test compares with.
const fs = require("fs");
const { PNG } = require("pngjs");
const BASIS = require("./basis_transcoder.cjs");
const [,, glbPath, outPath] = process.argv;
const glb = fs.readFileSync(glbPath);
const jsonLen = glb.readUInt32LE(12);
const json = JSON.parse(glb.subarray(20, 20 + jsonLen).toString());
const binStart = 20 + jsonLen + 8;
const view = json.bufferViews[json.images[0].bufferView];
const ktx = glb.subarray(binStart + (view.byteOffset || 0), binStart + (view.byteOffset || 0) + view.byteLength);
const wasmBinary = fs.readFileSync(require.resolve("three/examples/jsm/libs/basis/basis_transcoder.wasm"));
BASIS({ wasmBinary }).then((m) => {
  m.initializeBasis();
  const f = new m.KTX2File(new Uint8Array(ktx));
  if (!f.isValid() || !f.startTranscoding()) throw new Error("not valid");
  const w = f.getWidth(), h = f.getHeight();
  const RGBA32 = 13;
  const dst = new Uint8Array(f.getImageTranscodedSizeInBytes(0, 0, 0, RGBA32));
  if (!f.transcodeImage(dst, 0, 0, 0, RGBA32, 0, -1, -1)) throw new Error("transcode failed");
  const png = new PNG({ width: w, height: h });
  png.data = Buffer.from(dst);
  fs.writeFileSync(outPath, PNG.sync.write(png));
  console.log(glbPath, w, h, f.isUASTC() ? "UASTC" : "ETC1S");
});
