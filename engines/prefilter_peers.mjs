// The engines' own GGX prefilters, timed and read back for benchmarks/bench_prefilter_peers.py: three.js's
// PMREMGenerator.fromEquirectangular and Babylon.js's HDRFiltering.prefilter (on the cube its HDRCubeTexture makes
// of the panorama). Only the engines compute here; the page times their call to the end of the GPU's work
// (gl.finish, then a readPixels that cannot return before the last draw) and returns every level's texels.
import * as THREE from "three";
import { HDRLoader } from "three/examples/jsm/loaders/HDRLoader.js";
import { Engine } from "@babylonjs/core/Engines/engine.js";
import { Scene } from "@babylonjs/core/scene.js";
import { HDRCubeTexture } from "@babylonjs/core/Materials/Textures/hdrCubeTexture.js";
import { HDRFiltering } from "@babylonjs/core/Materials/Textures/Filtering/hdrFiltering.js";

const threeCanvas = document.getElementById("three");
const renderer = new THREE.WebGLRenderer({ canvas: threeCanvas });
const generator = new THREE.PMREMGenerator(renderer);
const engine = new Engine(document.getElementById("babylon"), false, { stencil: false });
const scene = new Scene(engine);

// Float texels of one face and mip level of a cube texture, rows as stored (row 0 = t = 0, the first row uploaded)
function readCubeLevel(gl, texture, face, level, size) {
  gl.getExtension("EXT_color_buffer_float");
  const fb = gl.createFramebuffer();
  gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
  gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_CUBE_MAP_POSITIVE_X + face, texture, level);
  const status = gl.checkFramebufferStatus(gl.FRAMEBUFFER);
  if (status !== gl.FRAMEBUFFER_COMPLETE) throw new Error(`framebuffer incomplete (${status}) at face ${face} level ${level}`);
  const pixels = new Float32Array(size * size * 4);
  gl.readPixels(0, 0, size, size, gl.RGBA, gl.FLOAT, pixels);
  gl.bindFramebuffer(gl.FRAMEBUFFER, null);
  gl.deleteFramebuffer(fb);
  return pixels;
}

// Every level (6 faces each) as one base64 string of float32 RGBA, level 0 first: far faster through Playwright
function levelsBase64(gl, texture, sizes) {
  const parts = [];
  sizes.forEach((size, level) => {
    for (let face = 0; face < 6; face++) parts.push(readCubeLevel(gl, texture, face, level, size));
  });
  const total = parts.reduce((n, p) => n + p.length, 0);
  const all = new Float32Array(total);
  let at = 0;
  for (const p of parts) { all.set(p, at); at += p.length; }
  const bytes = new Uint8Array(all.buffer);
  let text = "";
  for (let i = 0; i < bytes.length; i += 8192) text += String.fromCharCode(...bytes.subarray(i, i + 8192));
  return btoa(text);
}

// The GPU's work done: finish, then read one texel of the result (a read waits for every draw before it)
function drained(gl, texture) {
  gl.finish();
  readCubeLevel(gl, texture, 0, 0, 1);
}

// ---- three.js -------------------------------------------------------------------------------------------------------
let panorama = null;
let pmrem = null;

async function threeLoad(url) {
  panorama = await new HDRLoader().setDataType(THREE.FloatType).loadAsync(url);
  panorama.mapping = THREE.EquirectangularReflectionMapping;
  return [panorama.image.width, panorama.image.height];
}

// One PMREMGenerator.fromEquirectangular of the loaded panorama (the panorama's upload is not timed: it is uploaded
// by the warm-up call), in milliseconds
function threeRun() {
  if (pmrem) pmrem.dispose();
  const gl = renderer.getContext();
  gl.finish();
  const t0 = performance.now();
  pmrem = generator.fromEquirectangular(panorama);
  drained(gl, renderer.properties.get(pmrem.texture).__webglTexture);
  const ms = performance.now() - t0;
  renderer.resetState();  // the raw framebuffer calls above bypassed three.js's cache of the GL state
  return ms;
}

function threeLevels() {
  const sizes = pmrem.texture.mipmaps.map((m) => m.width);
  const roughness = sizes.map((_, lod) => THREE.PMREMGenerator.lodToRoughness(lod, sizes.length - 1));
  const gl = renderer.getContext();
  const data = levelsBase64(gl, renderer.properties.get(pmrem.texture).__webglTexture, sizes);
  renderer.resetState();
  return { sizes, roughness, data };
}

// ---- Babylon.js -----------------------------------------------------------------------------------------------------
let cube = null;

// A fresh HDRCubeTexture of the panorama (Babylon's own panorama → cube, with mips, no harmonics, not prefiltered):
// HDRFiltering replaces a texture's contents, so every timed run needs one
function babylonLoad(url, size) {
  if (cube) cube.dispose();
  return new Promise((resolve, reject) => {
    cube = new HDRCubeTexture(url, scene, size, false, false, false, false, () => resolve(size),
      (message) => reject(new Error(String(message))));
  });
}

// HDRFiltering.prefilter of the loaded cube, in milliseconds
async function babylonRun() {
  const gl = engine._gl;
  gl.finish();
  const t0 = performance.now();
  await new HDRFiltering(engine).prefilter(cube);
  drained(gl, cube.getInternalTexture()._hardwareTexture.underlyingResource);
  return performance.now() - t0;
}

function babylonLevels() {
  const size = cube.getSize().width;
  const sizes = [];
  for (let s = size; s >= 1; s >>= 1) sizes.push(s);
  const gl = engine._gl;
  return {
    sizes, scale: cube.lodGenerationScale, offset: cube.lodGenerationOffset,
    data: levelsBase64(gl, cube.getInternalTexture()._hardwareTexture.underlyingResource, sizes),
  };
}

Object.assign(window, { threeLoad, threeRun, threeLevels, babylonLoad, babylonRun, babylonLevels });
window.ready = true;
