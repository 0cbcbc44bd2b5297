// Babylon.js's default PBR shader lighting a sphere (white diffuse, or white metal of a given roughness), its
// environment (a) Babylon's own HDRCubeTexture of a panorama file (which computes the SphericalPolynomial on load,
// and prefilters the mips on the GPU when asked), (b) lightprobe's SphericalPolynomial export set on an otherwise
// black environment, (c) lightprobe's .env file through Babylon's CubeTexture, (d) lightprobe's glTF
// (EXT_lights_image_based) through Babylon's glTF loader; and the skybox each environment shows. Only Babylon
// renders; the page returns the pixels.
import { Engine } from "@babylonjs/core/Engines/engine.js";
import { Scene } from "@babylonjs/core/scene.js";
import { FreeCamera } from "@babylonjs/core/Cameras/freeCamera.js";
import { Vector3, Color4 } from "@babylonjs/core/Maths/math.js";
import { CreateSphere } from "@babylonjs/core/Meshes/Builders/sphereBuilder.js";
import { PBRMaterial } from "@babylonjs/core/Materials/PBR/pbrMaterial.js";
import { HDRCubeTexture } from "@babylonjs/core/Materials/Textures/hdrCubeTexture.js";
import { RawCubeTexture } from "@babylonjs/core/Materials/Textures/rawCubeTexture.js";
import { SphericalPolynomial } from "@babylonjs/core/Maths/sphericalPolynomial.js";
import { Constants } from "@babylonjs/core/Engines/constants.js";
import { CubeMapToSphericalPolynomialTools } from "@babylonjs/core/Misc/HighDynamicRange/cubemapToSphericalPolynomial.js";
import { CubeTexture } from "@babylonjs/core/Materials/Textures/cubeTexture.js";
import "@babylonjs/core/Materials/Textures/Loaders/envTextureLoader.js";
// BaseTexture.sphericalPolynomial is a side effect of this module; the .env loader registers it, the glTF loader
// does not (a full Babylon bundle has it)
import "@babylonjs/core/Materials/Textures/baseTexture.polynomial.js";
import "@babylonjs/core/Helpers/sceneHelpers.js";
import { AppendSceneAsync } from "@babylonjs/core/Loading/sceneLoader.js";
import { DirectionalLight } from "@babylonjs/core/Lights/directionalLight.js";
import "@babylonjs/core/Loading/loadingScreen.js";
import "@babylonjs/loaders/glTF/2.0/index.js";

// Babylon clamps HDR values at 4096 before projecting (its choice); the comparison is of the file's lighting, as in
// babylon_sh.mjs, so the clamp is lifted (the shipped probe's sun reaches 69120).
CubeMapToSphericalPolynomialTools.MAX_HDRI_VALUE = Number.MAX_VALUE;

const canvas = document.getElementById("c");

// The canvas's RGBA bytes (rows bottom to top, sRGB-encoded) as base64: far faster through Playwright than an array.
async function canvasBytes() {
  const bytes = await engine.readPixels(0, 0, canvas.width, canvas.height, true, true);
  let text = "";
  for (let i = 0; i < bytes.length; i += 8192) text += String.fromCharCode(...bytes.subarray(i, i + 8192));
  return btoa(text);
}
const engine = new Engine(canvas, false, { preserveDrawingBuffer: true, stencil: false });

async function renderSphere(environment, eye, exposure, png = false, roughness = null) {
  return (await renderSpheres(environment, eye, exposure, png, [roughness]))[0];
}

// One scene, one environment load, one image per roughness (null: the diffuse sphere)
function renderSpheres(environment, eye, exposure, png, roughnesses) {
  return renderViews(environment, roughnesses.map((roughness) => ({ eye, exposure, roughness })), png);
}

// One scene, one environment load, one image per view: {eye, exposure, roughness} (roughness null: diffuse)
async function renderViews(environment, views, png) {
  const scene = new Scene(engine);
  scene.clearColor = new Color4(0, 0, 0, 1);
  const camera = new FreeCamera("camera", Vector3.Zero(), scene);
  camera.fov = 0.55;
  const sphere = CreateSphere("sphere", { diameter: 2, segments: 64 }, scene);
  const material = new PBRMaterial("white", scene);
  material.albedoColor.set(1, 1, 1);
  material.environmentIntensity = 1;
  sphere.material = material;
  scene.imageProcessingConfiguration.toneMappingEnabled = false;
  scene.imageProcessingConfiguration.applyByPostProcess = false;
  scene.environmentTexture = await environment(scene);
  const results = [];
  for (const { eye, exposure, roughness } of views) {
    camera.position = new Vector3(...eye).scale(4);
    camera.setTarget(Vector3.Zero());
    scene.imageProcessingConfiguration.exposure = exposure;
    if (roughness === null) {
      material.metallic = 0; material.roughness = 1; material.metallicF0Factor = 0;  // diffuse only
    } else {
      material.metallic = 1; material.roughness = roughness; material.metallicF0Factor = 1;  // white metal
    }
    await scene.whenReadyAsync();
    scene.render();
    results.push(png ? canvas.toDataURL("image/png")
      : await canvasBytes());
  }
  scene.dispose();
  return results;
}

function fromPanorama(url, size, prefilter = false) {
  return (scene) => new Promise((resolve, reject) => {
    // generateHarmonics, linear; mips prefiltered by Babylon's HDRFiltering only when asked (glossy checks)
    const texture = new HDRCubeTexture(url, scene, size, !prefilter, true, false, prefilter, () => resolve(texture),
                                       (message) => reject(new Error(message)));
  });
}

function fromEnvFile(url) {
  return (scene) => new Promise((resolve, reject) => {
    const texture = CubeTexture.CreateFromPrefilteredData(url, scene, ".env");
    texture.onLoadObservable.addOnce(() => resolve(texture));
    setTimeout(() => reject(new Error(`${url}: not loaded after 60 s`)), 60000);
  });
}

function fromGltf(url) {
  return async (scene) => {
    await AppendSceneAsync(url, scene);
    if (!scene.environmentTexture) throw new Error(`${url}: the glTF loader set no environment`);
    await new Promise((resolve) => scene.environmentTexture.isReady()
      ? resolve() : scene.environmentTexture.onLoadObservable.addOnce(resolve));
    return scene.environmentTexture;
  };
}

async function renderSkybox(environment, directions, exposure) {
  // the camera at the centre looking along each direction (Babylon's frame), the environment as Babylon's skybox
  const scene = new Scene(engine);
  const camera = new FreeCamera("camera", Vector3.Zero(), scene);
  camera.fov = 1.2;
  camera.minZ = 0.1;
  scene.imageProcessingConfiguration.toneMappingEnabled = false;
  scene.imageProcessingConfiguration.exposure = exposure;
  scene.imageProcessingConfiguration.applyByPostProcess = false;
  const texture = await environment(scene);
  scene.createDefaultSkybox(texture, true, 100, 0);
  const results = [];
  for (const direction of directions) {
    // an up vector off the view axis, so looking straight up or down is defined
    camera.upVector = Math.abs(direction[1]) > 0.9 ? new Vector3(0, 0, 1) : new Vector3(0, 1, 0);
    camera.setTarget(new Vector3(...direction));
    await scene.whenReadyAsync();
    scene.render();
    results.push(await canvasBytes());
  }
  scene.dispose();
  return results;
}

const sources = {
  panorama: ([url, size]) => fromPanorama(url, size),
  prefiltered: ([url, size]) => fromPanorama(url, size, true),
  polynomial: ([array]) => fromPolynomial(array),
  env: ([url]) => fromEnvFile(url),
  gltf: ([url]) => fromGltf(url),
};

function fromPolynomial(array) {
  return async (scene) => {
    const black = new Uint8Array(4);
    const texture = new RawCubeTexture(scene, [black, black, black, black, black, black], 1);
    texture.sphericalPolynomial = SphericalPolynomial.FromArray(array);
    return texture;
  };
}

// Each returns the canvas bytes (see canvasBytes), the camera at 4 × eye looking at the sphere's centre.
// `source` names one of `sources` with its arguments; `roughness` null for the diffuse sphere.
window.lightprobe = {
  panorama: (url, size, eye, exposure, png) => renderSphere(fromPanorama(url, size), eye, exposure, png),
  polynomial: (array, eye, exposure, png) => renderSphere(fromPolynomial(array), eye, exposure, png),
  sphere: (source, args, eye, exposure, roughness, png) =>
    renderSphere(sources[source](args), eye, exposure, png, roughness),
  spheres: (source, args, eye, exposure, roughnesses) =>
    renderSpheres(sources[source](args), eye, exposure, false, roughnesses),
  // several views of one environment load: [{eye, exposure, roughness}, …]
  views: (source, args, views, png) => renderViews(sources[source](args), views, png),
  skyboxes: (source, args, directions, exposure) => renderSkybox(sources[source](args), directions, exposure),
  // the SphericalPolynomial Babylon holds for an environment (x, y, z, xx, yy, zz, yz, zx, xy; RGB each)
  polynomialOf: async (source, args) => {
    const scene = new Scene(engine);
    const texture = await sources[source](args)(scene);
    const p = texture.sphericalPolynomial;
    const result = ["x", "y", "z", "xx", "yy", "zz", "yz", "zx", "xy"].map((k) => p[k].asArray());
    scene.dispose();
    return result;
  },
};
// Directional lights as Babylon holds them, each as the direction toward the light (−its world direction) with its
// intensity and diffuse colour: from a glTF through Babylon's loader (KHR_lights_punctual, nodes and the loader's
// change of handedness applied by Babylon), or from our Babylon JSON through the DirectionalLight constructor.
function lightsOf(scene) {
  return scene.lights.filter((l) => l instanceof DirectionalLight).map((l) => {
    l.computeWorldMatrix(true);
    if (l.parent) l.computeTransformedInformation();
    const d = l.parent ? l.transformedDirection : l.direction;
    return { toward: d.normalizeToNew().scale(-1).asArray(), intensity: l.intensity, diffuse: l.diffuse.asArray() };
  });
}
window.lightprobe.gltfLights = async (url) => {
  const scene = new Scene(engine);
  await AppendSceneAsync(url, scene);
  const lights = lightsOf(scene);
  scene.dispose();
  return lights;
};
window.lightprobe.jsonLights = (text) => {
  const scene = new Scene(engine);
  for (const l of JSON.parse(text).directionalLights) {
    const light = new DirectionalLight(l.name, Vector3.FromArray(l.direction), scene);
    light.intensity = l.intensity;
  }
  const lights = lightsOf(scene);
  scene.dispose();
  return lights;
};
window.ready = true;
