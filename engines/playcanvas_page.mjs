// PlayCanvas's StandardMaterial lighting a sphere (white diffuse, or white metal of a given roughness: gloss =
// 1 − roughness) from scene.envAtlas + scene.skybox, either (a) lightprobe's baked envAtlas.png and skybox faces,
// loaded by PlayCanvas's own texture and cubemap asset handlers, or (b) PlayCanvas's own EnvLighting of a panorama
// file (its .hdr loader, generateLightingSource → generateAtlas, generateSkyboxCubemap); and the skybox each shows.
// Only PlayCanvas renders; the page returns the pixels.
import * as pc from "./node_modules/playcanvas/build/playcanvas.mjs";

const canvas = document.getElementById("c");
const app = new pc.Application(canvas, {
  graphicsDeviceOptions: { preserveDrawingBuffer: true, antialias: false, alpha: false, deviceTypes: ["webgl2"] },
});
app.setCanvasFillMode(pc.FILLMODE_NONE);
app.setCanvasResolution(pc.RESOLUTION_FIXED, canvas.width, canvas.height);
app.autoRender = false;
app.start();

const camera = new pc.Entity("camera");
camera.addComponent("camera", {
  clearColor: new pc.Color(0, 0, 0, 1), fov: 32, nearClip: 0.05, farClip: 100,
  toneMapping: pc.TONEMAP_LINEAR, gammaCorrection: pc.GAMMA_SRGB,
});
app.root.addChild(camera);
const material = new pc.StandardMaterial();
const sphere = new pc.Entity("sphere");
sphere.addComponent("render", { type: "sphere", material });
sphere.setLocalScale(2, 2, 2);  // PlayCanvas's sphere primitive has radius 0.5
app.root.addChild(sphere);

function load(asset) {
  return new Promise((resolve, reject) => {
    asset.once("load", () => resolve(asset));
    asset.once("error", (e) => reject(new Error(`${asset.name}: ${e}`)));
    app.assets.add(asset);
    app.assets.load(asset);
  });
}

// Our bake: the envAtlas PNG and the six skybox faces through PlayCanvas's asset handlers
async function baked(folderUrl) {
  const atlas = await load(new pc.Asset("envAtlas", "texture", { url: `${folderUrl}/envAtlas.png` },
    { type: "rgbp", mipmaps: false }));
  const faces = ["px", "nx", "py", "ny", "pz", "nz"].map((f) => `${folderUrl}/skybox_${f}.png`);
  const sky = await load(new pc.Asset("skybox", "cubemap", null, { textures: faces, type: "rgbp", mipmaps: false }));
  return { atlas: atlas.resource, skybox: sky.resources[0] };
}

// PlayCanvas's own path from a panorama file: what its examples do at load time. Its lighting source cube is a
// quarter of the atlas wide (as wide as the atlas's mirror image; 128 by default for the default 512 atlas); no
// atlas when atlasSize is 0 (the skybox views need none)
async function own(panoramaUrl, atlasSize, skyboxSize) {
  const source = (await load(new pc.Asset("panorama", "texture", { url: panoramaUrl },
    { mipmaps: false }))).resource;
  const skybox = pc.EnvLighting.generateSkyboxCubemap(source, skyboxSize);
  if (!atlasSize) return { atlas: null, skybox };
  const lighting = pc.EnvLighting.generateLightingSource(source, { size: atlasSize / 4 });
  const atlas = pc.EnvLighting.generateAtlas(lighting, { size: atlasSize });
  lighting.destroy();
  return { atlas, skybox };
}

async function environment(source, args) {
  return source === "baked" ? baked(...args) : own(...args);
}

function readCanvas() {
  const gl = app.graphicsDevice.gl;
  const bytes = new Uint8Array(canvas.width * canvas.height * 4);
  gl.readPixels(0, 0, canvas.width, canvas.height, gl.RGBA, gl.UNSIGNED_BYTE, bytes);
  let text = "";
  for (let i = 0; i < bytes.length; i += 8192) text += String.fromCharCode(...bytes.subarray(i, i + 8192));
  return btoa(text);
}

function render() {
  app.update(0);
  app.render();
  return readCanvas();
}

function useEnvironment(env, exposure) {
  app.scene.envAtlas = env.atlas;
  app.scene.skybox = env.skybox;
  app.scene.skyboxMip = 0;
  app.scene.exposure = exposure;
}

function look(eye, target, up) {
  camera.setPosition(...eye);
  camera.lookAt(new pc.Vec3(...target), new pc.Vec3(...up));
}

// The directional lights of a bake's lights.json, made as its USAGE.md makes them (PlayCanvas's frame; a light
// shines along its entity's −Y; PlayCanvas linearises the colour it is given, and below intensity 1 colour ×
// intensity, so it is handed the sRGB of the linear colour, times the intensity below 1)
async function addLights(url) {
  const found = await (await fetch(url)).json();
  for (const l of found.directionalLights) {
    const k = Math.min(l.intensity, 1);
    const e = new pc.Entity();
    e.addComponent("light", { type: "directional", color: new pc.Color(...l.colour.map((v) => v * k)).gamma(),
      intensity: Math.max(l.intensity, 1), castShadows: false });
    e.lookAt(...l.travel); e.rotateLocal(90, 0, 0);
    app.root.addChild(e);
  }
}

window.lightprobe = {
  addLights,
  // one image per view {roughness, exposure} (roughness null: the diffuse sphere), the camera at 4·eye looking at
  // the sphere. One environment per page: the test opens a fresh page for each (a second environment in the same
  // application rendered the metals wrong: see run() in tests/test_bake_playcanvas.py)
  async spheres(source, args, eye, views) {
    const env = await environment(source, args);
    useEnvironment(env, 1);
    sphere.enabled = true;
    look(eye.map((v) => 4 * v), [0, 0, 0], Math.abs(eye[1]) > 0.99 ? [1, 0, 0] : [0, 1, 0]);
    const images = [];
    for (const { roughness, exposure } of views) {
      app.scene.exposure = exposure;
      material.diffuse = new pc.Color(1, 1, 1);
      material.useMetalness = true;
      if (roughness === null) {  // diffuse only: no environment reflection at all
        material.metalness = 0; material.gloss = 0; material.reflectivity = 0;
        material.specular = new pc.Color(0, 0, 0);
      } else {  // white metal
        material.metalness = 1; material.gloss = 1 - roughness; material.reflectivity = 1;
      }
      material.update();
      images.push(render());
    }
    return images;
  },
  // the skybox alone, looking along each view direction from the origin
  async skyboxes(source, args, views, exposure) {
    const env = await environment(source, args);
    useEnvironment(env, exposure);
    sphere.enabled = false;
    const images = views.map((v) => {
      look([0, 0, 0], v, Math.abs(v[1]) > 0.99 ? [0, 0, -1] : [0, 1, 0]);
      return render();
    });
    sphere.enabled = true;
    return images;
  },
};
window.ready = true;
