// Reads KTX1 files with Filament's own web build (npm `filament`, its C++ image::Ktx1Bundle compiled to WebAssembly),
// in Node: no engine or WebGL is needed to parse. Usage: node filament_ktx1_check.mjs FILE...  Prints one JSON array:
// for each file Ktx1Bundle's info(), level count, cube flag, the "sh" metadata, the 27 numbers Filament's own
// createIblFromKtx1 takes from it (the same split and parseFloat), and each level's blob (base64).
import { readFileSync } from "node:fs";
import { createRequire } from "node:module";
import path from "node:path";
import vm from "node:vm";

// filament.js is an Emscripten script for a page's global scope: run it as one, with the names it expects in Node
const file = path.resolve(path.dirname(new URL(import.meta.url).pathname), "node_modules/filament/filament.js");
Object.assign(globalThis, { require: createRequire(file), __filename: file, __dirname: path.dirname(file) });
vm.runInThisContext(readFileSync(file, "utf8"), { filename: file });

const b64 = (u8) => Buffer.from(u8.buffer, u8.byteOffset, u8.byteLength).toString("base64");
globalThis.Filament.init([], () => {
  const F = globalThis.Filament;
  const out = process.argv.slice(2).map((name) => {
    const bytes = new Uint8Array(readFileSync(name));
    const buffer = F.Buffer(bytes);
    const ktx = new F.Ktx1Bundle(buffer);
    const info = ktx.info();
    const levels = ktx.getNumMipLevels();
    const cube = ktx.isCubemap();
    const blobs = [];
    for (let i = 0; i < levels; i++) blobs.push(b64(cube ? ktx.getCubeBlob(i) : ktx.getBlob([i, 0, 0])));
    const sh = ktx.getMetadata("sh");
    const fields = ["endianness", "glType", "glTypeSize", "glFormat", "glInternalFormat", "glBaseInternalFormat",
                    "pixelWidth", "pixelHeight", "pixelDepth"];
    const result = { info: Object.fromEntries(fields.map((k) => [k, info[k]])), levels, cube, sh, shFloats: sh ? sh.split(/\s/, 9 * 3).map(parseFloat) : null,
                     blobs };
    ktx.delete();
    buffer.delete();
    return result;
  });
  process.stdout.write(JSON.stringify(out));
});
