// Babylon.js's own CPU path from a panorama to lighting, and Babylon's own handling of lightprobe's exports.
// Reads a JSON request on stdin, writes one JSON answer on stdout. Only Babylon's code computes here:
//   panorama: HDRTools.GetCubeMapTextureData (RGBE → cube faces) → CubeMapToSphericalPolynomialTools
//             .ConvertCubeMapToSphericalPolynomial → SphericalPolynomial, and its preScaledHarmonics;
//   exports:  SphericalPolynomial.FromArray(our polynomial) → preScaledHarmonics (what the default PBR shader reads).
import { readFileSync } from "node:fs";
import { GetCubeMapTextureData } from "@babylonjs/core/Misc/HighDynamicRange/hdr.js";
import { CubeMapToSphericalPolynomialTools } from "@babylonjs/core/Misc/HighDynamicRange/cubemapToSphericalPolynomial.js";
import { SphericalPolynomial } from "@babylonjs/core/Maths/sphericalPolynomial.js";

const request = JSON.parse(readFileSync(0, "utf8"));
const v3 = (v) => [v.x, v.y, v.z];
const harmonicsArray = (h) => [h.l00, h.l1_1, h.l10, h.l11, h.l2_2, h.l2_1, h.l20, h.l21, h.l22].map(v3);
const polynomialArray = (p) => ["x", "y", "z", "xx", "yy", "zz", "yz", "zx", "xy"].map((k) => v3(p[k]));

// Babylon clamps HDR values at MAX_HDRI_VALUE (4096) before projecting; the comparison is of the lighting in the
// file, so the clamp is lifted (a sun of the shipped probe reaches 69120).
CubeMapToSphericalPolynomialTools.MAX_HDRI_VALUE = Number.MAX_VALUE;

function brightest(cube) {
  // the direction of the brightest cube texel, placed by Babylon's own face table and texel centres
  let best = -1, direction = null;
  const stride = cube.format === 5 ? 4 : 3;
  for (const face of CubeMapToSphericalPolynomialTools._FileFaces) {
    const data = cube[face.name];
    for (let y = 0; y < cube.size; y++) {
      for (let x = 0; x < cube.size; x++) {
        const i = (y * cube.size + x) * stride;
        const value = 0.2126 * data[i] + 0.7152 * data[i + 1] + 0.0722 * data[i + 2];
        if (value > best) {
          const u = (2 * x + 1) / cube.size - 1, v = (2 * y + 1) / cube.size - 1;
          best = value;
          direction = face.worldAxisForFileX.scale(u).add(face.worldAxisForFileY.scale(v)).add(face.worldAxisForNormal)
            .normalize();
        }
      }
    }
  }
  return v3(direction);
}

function fromPanorama(path, size, supersample) {
  const bytes = readFileSync(path);
  const buffer = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength);
  const cube = GetCubeMapTextureData(buffer, size, supersample);
  const polynomial = CubeMapToSphericalPolynomialTools.ConvertCubeMapToSphericalPolynomial(cube);
  return { polynomial: polynomialArray(polynomial), preScaledHarmonics: harmonicsArray(polynomial.preScaledHarmonics),
           brightest: brightest(cube) };
}

function fromExport(text) {
  const data = JSON.parse(text);
  const polynomial = SphericalPolynomial.FromArray(data.polynomial);
  return { polynomial: polynomialArray(polynomial), preScaledHarmonics: harmonicsArray(polynomial.preScaledHarmonics) };
}

const answer = {};
for (const [key, job] of Object.entries(request)) {
  answer[key] = job.panorama ? fromPanorama(job.panorama, job.size, Boolean(job.supersample)) : fromExport(job.export);
}
process.stdout.write(JSON.stringify(answer));
