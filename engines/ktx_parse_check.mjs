// Reads KTX2 files with ktx-parse (npm, pinned in package.json) — an independent reader of lightprobe's KTX2 writer.
// Usage: node ktx_parse_check.mjs FILE...  Prints one JSON array: for each file what ktx-parse found, the level
// bytes as stored (base64; supercompressed levels stay compressed: ktx-parse does not inflate them).
import { readFileSync } from "node:fs";
import { read } from "ktx-parse";

const b64 = (u8) => Buffer.from(u8.buffer, u8.byteOffset, u8.byteLength).toString("base64");
const out = process.argv.slice(2).map((path) => {
  const c = read(new Uint8Array(readFileSync(path)));
  const keyValue = {};
  for (const [key, value] of Object.entries(c.keyValue)) {
    keyValue[key] = typeof value === "string" ? { text: value } : { base64: b64(value) };
  }
  return {
    vkFormat: c.vkFormat, typeSize: c.typeSize, pixelWidth: c.pixelWidth, pixelHeight: c.pixelHeight,
    pixelDepth: c.pixelDepth, layerCount: c.layerCount, faceCount: c.faceCount, levelCount: c.levelCount,
    supercompressionScheme: c.supercompressionScheme, dataFormatDescriptor: c.dataFormatDescriptor, keyValue,
    globalData: c.globalData,
    levels: c.levels.map((l) => ({ byteLength: l.levelData.byteLength, uncompressedByteLength: l.uncompressedByteLength,
                                   base64: b64(l.levelData) })),
  };
});
process.stdout.write(JSON.stringify(out));
