// lightprobe view: the bake (bake/bake.json, made by lightprobe.viewer.bake) on the user's mesh, live.
// three.js carries the scene, the camera and the render loop; the lighting is lightprobe's own shaders (shaders.js),
// except for the "threejs" method, which is three.js's own LightProbe fed lightprobe's threejs export.
// window.lightprobe is the page's API for the tests and the demo (render, synthesize, frameTime, setState).
import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";
import * as GLSL from "./shaders.js";

const METHODS = {
  sh: "eq. 13 per pixel — Ramamoorthi & Hanrahan 2001",
  "sh-vertex": "eq. 13 per vertex — the paper's hardware path",
  threejs: "three.js's own LightProbe, fed lightprobe's threejs export",
  lights: "area lights with soft shadows + ambient SH — Arbree, Walter & Bala 2005",
  rsibr: "RS-IBR, one map per frame synthesised on the GPU — Cabral, Olano & Nemec 1999",
  "rsibr-pixel": "RS-IBR, each pixel's own view blended",
  splitsum: "split sum (Karis 2013), for comparison",
  basis: "an SH basis function Y_lm (red > 0, blue < 0)",
};
const GLOSSY = new Set(["rsibr", "rsibr-pixel", "splitsum"]);
const SH_NAMES = ["Y00", "Y1−1", "Y10", "Y11", "Y2−2", "Y2−1", "Y20", "Y21", "Y22"];
const TONEMAPS = { aces: 0, reinhard: 1, linear: 2 };
const ATLAS = 2048, TILES = 4;  // the shadow atlas: 4 × 4 tiles of 512², one per shadowed light
const MAX_LIGHTS = 32;  // as the shader's
// three.js shows an equirectangular background with its centre at +X: the same light sits at (−z, y, x) of
// lightprobe's world (lightprobe.frames.THREEJS), the frame its threejs export is stated in.
const TO_THREEJS = new THREE.Matrix4().set(0, 0, -1, 0, 0, 1, 0, 0, 1, 0, 0, 0, 0, 0, 0, 1);

// ---- SH helpers (JS) --------------------------------------------------------------------------------------------
const C1 = 0.429043, C2 = 0.511664, C3 = 0.743125, C4 = 0.886227, C5 = 0.247708;

// Eq. 12's matrix of one channel from nine radiance coefficients L (lightprobe.irradiance.irradiance_matrices).
function irradianceMatrix(L) {
  const [l00, l1m1, l10, l11, l2m2, l2m1, l20, l21, l22] = L;
  return new THREE.Matrix4().set(
    C1 * l22, C1 * l2m2, C1 * l21, C2 * l11,
    C1 * l2m2, -C1 * l22, C1 * l2m1, C2 * l1m1,
    C1 * l21, C1 * l2m1, C3 * l20, C2 * l10,
    C2 * l11, C2 * l1m1, C2 * l10, C4 * l00 - C5 * l20);
}

function basis9(d) {
  const [x, y, z] = d;
  return [0.282095, 0.488603 * y, 0.488603 * z, 0.488603 * x, 1.092548 * x * y, 1.092548 * y * z,
    0.315392 * (3 * z * z - 1), 1.092548 * x * z, 0.546274 * (x * x - y * y)];
}

// Coefficients (9 × RGB, flat) of f'(d) = f(Rᵀd): bands ≤ 2 rotate exactly, so a least-squares fit on enough
// directions recovers them.
function rotateSH9(flat, R) {
  const dirs = [], n = 64;
  for (let i = 0; i < n; i++) {
    const z = 1 - (2 * i + 1) / n, r = Math.sqrt(1 - z * z), a = i * 2.399963;
    dirs.push(new THREE.Vector3(r * Math.cos(a), r * Math.sin(a), z));
  }
  const Rt = R.clone().transpose();
  const A = dirs.map((d) => basis9(d.toArray()));
  const B = dirs.map((d) => basis9(d.clone().applyMatrix3(Rt).toArray()));
  const AtA = Array.from({ length: 9 }, (_, i) => Array.from({ length: 9 }, (_, j) => A.reduce((s, a) => s + a[i] * a[j], 0)));
  const out = new Array(27).fill(0);
  for (let ch = 0; ch < 3; ch++) {
    const f = B.map((b) => b.reduce((s, y, j) => s + y * flat[3 * j + ch], 0));
    const rhs = Array.from({ length: 9 }, (_, i) => A.reduce((s, a, k) => s + a[i] * f[k], 0));
    const x = solve(AtA.map((row) => row.slice()), rhs);
    for (let i = 0; i < 9; i++) out[3 * i + ch] = x[i];
  }
  return out;
}

function solve(M, b) {  // Gaussian elimination with partial pivoting
  const n = b.length;
  for (let c = 0; c < n; c++) {
    let p = c;
    for (let r = c + 1; r < n; r++) if (Math.abs(M[r][c]) > Math.abs(M[p][c])) p = r;
    [M[c], M[p]] = [M[p], M[c]]; [b[c], b[p]] = [b[p], b[c]];
    for (let r = c + 1; r < n; r++) {
      const f = M[r][c] / M[c][c];
      for (let k = c; k < n; k++) M[r][k] -= f * M[c][k];
      b[r] -= f * b[c];
    }
  }
  const x = new Array(n).fill(0);
  for (let r = n - 1; r >= 0; r--) {
    let s = b[r];
    for (let k = r + 1; k < n; k++) s -= M[r][k] * x[k];
    x[r] = s / M[r][r];
  }
  return x;
}

// lightprobe.radiance.view_frame as a Matrix3 (columns right, up, v).
function viewFrame(v) {
  const hint = Math.abs(v.y) <= 0.99 ? new THREE.Vector3(0, 1, 0) : new THREE.Vector3(0, 0, -1);
  const right = new THREE.Vector3().crossVectors(hint, v).normalize();
  const up = new THREE.Vector3().crossVectors(v, right);
  return new THREE.Matrix3().set(right.x, up.x, v.x, right.y, up.y, v.y, right.z, up.z, v.z);
}

function rowsToMatrix3(T) { return new THREE.Matrix3().set(...T[0], ...T[1], ...T[2]); }

// lightprobe.rsibr.blend_weights: the view-mesh triangle around v and its spherical barycentric weights.
function blendWeights(views, triangles, v) {
  const V = views.map((a) => new THREE.Vector3(...a));
  const triple = (a, b) => v.dot(new THREE.Vector3().crossVectors(a, b));
  let best = -Infinity, tri = triangles[0];
  for (const t of triangles) {
    const [a, b, c] = t.map((i) => V[i]);
    const m = Math.min(triple(a, b), triple(b, c), triple(c, a));
    if (m > best) { best = m; tri = t; }
  }
  const excess = (a, b, c) => 2 * Math.atan2(Math.abs(a.dot(new THREE.Vector3().crossVectors(b, c))),
    1 + a.dot(b) + b.dot(c) + c.dot(a));
  const [a, b, c] = tri.map((i) => V[i]);
  const w = [excess(v, b, c), excess(a, v, c), excess(a, b, v)];
  const s = Math.max(w[0] + w[1] + w[2], 1e-300);
  return { sources: tri, weights: w.map((x) => x / s) };
}

// ---- loading the bake -----------------------------------------------------------------------------------------------
async function floats(part) {
  const res = await fetch("bake/" + part.file);
  if (!res.ok) throw new Error(`bake/${part.file}: ${res.status}`);
  const data = new Float32Array(await res.arrayBuffer());
  const expected = part.shape.reduce((a, b) => a * b, 1);
  if (data.length !== expected) throw new Error(`bake/${part.file}: ${data.length} floats, expected ${expected}`);
  return data;
}

function rgba(rgb) {
  const out = new Float32Array((rgb.length / 3) * 4);
  for (let i = 0, j = 0; i < rgb.length; i += 3, j += 4) {
    out[j] = rgb[i]; out[j + 1] = rgb[i + 1]; out[j + 2] = rgb[i + 2]; out[j + 3] = 1;
  }
  return out;
}

function dataTexture(data, w, h) {
  const t = new THREE.DataTexture(rgba(data), w, h, THREE.RGBAFormat, THREE.FloatType);
  t.minFilter = t.magFilter = THREE.NearestFilter;
  t.needsUpdate = true;
  return t;
}

async function latlongTexture(part) {
  const [h, w] = part.shape;
  return dataTexture(await floats(part), w, h);
}

async function arrayTexture(part) {
  const [n, s] = part.shape;
  const t = new THREE.DataArrayTexture(rgba(await floats(part)), s, s, n);
  t.format = THREE.RGBAFormat; t.type = THREE.FloatType;
  t.minFilter = t.magFilter = THREE.NearestFilter;
  t.needsUpdate = true;
  return t;
}

// ---- the viewer ---------------------------------------------------------------------------------------------------
class Viewer {
  async init() {
    this.bake = await (await fetch("bake/bake.json")).json();
    const bake = this.bake;
    this.canvas = document.getElementById("canvas");
    this.renderer = new THREE.WebGLRenderer({ canvas: this.canvas, preserveDrawingBuffer: true });
    this.renderer.autoClear = false;
    this.renderer.toneMapping = THREE.NoToneMapping;
    this.state = { method: "sh", brdf: 0, basis: 0, exposure: 0, tonemap: "aces", rotation: 0, background: true,
      design: new Array(9).fill(1), shadows: true };
    this.frameMs = NaN;
    this.synth = { frame: { value: new THREE.Matrix3() } };  // the frame of this frame's synthesised map

    const [background, ambient, glb] = await Promise.all([latlongTexture(bake.background),
      latlongTexture(bake.lights.ambient), new GLTFLoader().loadAsync("bake/mesh.glb")]);
    this.lightsDoc = await (await fetch("bake/" + bake.lights.file)).json();
    this.threeDoc = await (await fetch("bake/" + bake.threejs)).json();
    this.brdfs = [];
    for (const part of bake.brdfs) {
      const entry = { part, maps: await arrayTexture(part.maps) };
      if (part.splitsum) entry.prefiltered = await latlongTexture(part.splitsum);
      this.brdfs.push(entry);
    }
    this.shared = {
      envFromWorld: { value: new THREE.Matrix3() }, Mr: { value: new THREE.Matrix4() },
      Mg: { value: new THREE.Matrix4() }, Mb: { value: new THREE.Matrix4() }, ambientMap: { value: ambient },
      basisIndex: { value: 0 },
    };
    this.setupMeshes(glb.scene);
    this.setupLights();
    this.setupThree();
    this.setupScreens(background);
    this.camera = new THREE.PerspectiveCamera(bake.camera.fov, 1, 0.01, 200);
    this.controls = new OrbitControls(this.camera, this.canvas);
    this.controls.maxPolarAngle = 0.495 * Math.PI;  // stay above the ground plane: the objects stand on it
    this.resetCamera();
    this.controls.addEventListener("change", () => this.requestFrame());
    this.updateCoefficients();
    this.setupPanel();
    new ResizeObserver(() => this.requestFrame()).observe(this.canvas);
    this.requestFrame();
  }

  resetCamera(c = this.bake.camera) {
    this.camera.fov = c.fov;
    this.camera.up.set(...c.up);
    this.camera.position.set(...c.eye);
    this.controls.target.set(...c.target);
    this.camera.lookAt(this.controls.target);
    this.camera.updateProjectionMatrix();
    this.controls.update();
  }

  setupMeshes(root) {
    this.scene = new THREE.Scene();
    this.meshes = [];
    const info = Object.fromEntries(this.bake.meshes.map((m) => [m.name, m]));
    root.updateMatrixWorld(true);
    root.traverse((o) => {
      if (!o.isMesh) return;
      let name = o.name, p = o;
      while (!info[name] && p.parent) { p = p.parent; name = p.name; }
      const m = info[name] || { name, albedo: [0.8, 0.8, 0.8] };
      const mesh = new THREE.Mesh(o.geometry, undefined);
      mesh.applyMatrix4(o.matrixWorld);
      mesh.userData = { name: m.name, albedo: new THREE.Vector3(...m.albedo), ground: m.name === "ground" };
      this.meshes.push(mesh);
      this.scene.add(mesh);
    });
    this.materials = {};
    const box = new THREE.Box3();
    for (const m of this.meshes) if (!m.userData.ground) box.expandByObject(m);
    this.bounds = box.getBoundingSphere(new THREE.Sphere());
  }

  // One material per method and mesh, sharing the lighting uniforms; built when first used.
  material(method, mesh) {
    const key = `${method}/${this.state.brdf}/${mesh.userData.name}`;
    if (this.materials[key]) return this.materials[key];
    let mat;
    if (method === "threejs") throw new Error("threejs draws its own scene");
    const defines = { sh: { SH_PIXEL: 1 }, "sh-vertex": { SH_VERTEX: 1 }, basis: { BASIS: 1 }, lights: { LIGHTS: 1 },
      rsibr: { GLOSSY: 1, RSIBR_FRAME: 1 }, "rsibr-pixel": { GLOSSY: 1, RSIBR_PIXEL: 1 },
      splitsum: { SPLITSUM: 1 } }[method];
    const uniforms = { ...this.shared, albedo: { value: mesh.userData.albedo },
      objectId: { value: mesh.userData.ground ? 2 : 1 }, glossy: { value: !mesh.userData.ground } };
    if (method === "lights") Object.assign(uniforms, this.lightUniforms);
    const brdf = this.brdfs[this.state.brdf];
    if (GLOSSY.has(method)) {
      if (!brdf) throw new Error("this bake holds no BRDF: bake with --brdf");
      Object.assign(uniforms, { radianceMaps: { value: brdf.maps },
        mirrorWarp: { value: brdf.part.central === "mirror" } });
      if (method === "rsibr") Object.assign(uniforms, this.synthUniforms());
      if (method === "rsibr-pixel") {
        defines.VIEWS = brdf.part.views.length; defines.TRIANGLES = brdf.part.triangles.length;
        uniforms.views = { value: new Float32Array(brdf.part.views.flat()) };
        uniforms.triangles = { value: new Int32Array(brdf.part.triangles.flat()) };
        const V = brdf.part.views.map((a) => new THREE.Vector3(...a));
        uniforms.edges = { value: new Float32Array(brdf.part.triangles.flatMap(([a, b, c]) =>
          [[a, b], [b, c], [c, a]].flatMap(([i, j]) => new THREE.Vector3().crossVectors(V[i], V[j]).toArray()))) };
      }
      if (method === "splitsum") {
        if (!brdf.part.splitsum) throw new Error(`splitsum is defined for GGX, not ${brdf.part.spec}`);
        Object.assign(uniforms, { prefiltered: { value: brdf.prefiltered },
          dfg: { value: new Float32Array(brdf.part.splitsum.dfg.flat()) },
          f0: { value: new THREE.Vector3(...brdf.part.splitsum.f0) } });
      }
    }
    mat = new THREE.ShaderMaterial({ glslVersion: THREE.GLSL3, defines, uniforms,
      vertexShader: GLSL.COMMON + GLSL.OBJECT_VERTEX, fragmentShader: GLSL.COMMON + GLSL.OBJECT_FRAGMENT,
      side: THREE.DoubleSide });
    this.materials[key] = mat;
    return mat;
  }

  // ---- eq. 13 and the sliders -----------------------------------------------------------------------------------
  coefficients() {  // the bake's L_lm (9 × RGB), each times its slider's factor
    return this.bake.sh.coefficients.map((rgb, i) => rgb.map((c) => c * this.state.design[i]));
  }

  updateCoefficients() {
    const L = this.coefficients();
    ["Mr", "Mg", "Mb"].forEach((u, ch) => this.shared[u].value.copy(irradianceMatrix(L.map((c) => c[ch]))));
  }

  rotation() {  // the environment turned about +Y by the slider's angle: light from d now comes from R·d
    return new THREE.Matrix3().setFromMatrix4(new THREE.Matrix4().makeRotationY(this.state.rotation * Math.PI / 180));
  }

  // ---- lights and their shadow maps ---------------------------------------------------------------------------------
  setupLights() {
    const lights = this.lightsDoc.lights;
    // Up to MAX_LIGHTS lights shade (a decomposition rarely finds more); the first TILES² cast shadows, the rest
    // (the faintest: the lights come brightest first) light unshadowed.
    const n = MAX_LIGHTS;
    this.lightCount = Math.min(lights.length, n);
    this.lightUniforms = {
      lightCount: { value: this.lightCount },
      lightDir: { value: new Float32Array(3 * n) }, lightRadiance: { value: new Float32Array(3 * n) },
      lightRadius: { value: new Float32Array(n) }, lightRight: { value: new Float32Array(3 * n) },
      lightUp: { value: new Float32Array(3 * n) }, lightShadowed: { value: new Int32Array(n) },
      lightTile: { value: new Float32Array(4 * n) }, shadows: { value: true },
      shadowCentre: { value: this.bounds.center.clone() }, shadowExtent: { value: 2.1 * this.bounds.radius },
      heightLow: { value: 0 }, heightRange: { value: 1 },
    };
    const u = this.lightUniforms;
    lights.slice(0, n).forEach((l, k) => {
      u.lightDir.value.set(l.direction, 3 * k);
      u.lightRadiance.value.set(l.radiance, 3 * k);
      u.lightRadius.value[k] = l.angular_radius_deg * Math.PI / 180;
      u.lightShadowed.value[k] = k < TILES * TILES ? 1 : 0;
      if (k < TILES * TILES) u.lightTile.value.set([(k % TILES) / TILES, Math.floor(k / TILES) / TILES, 1 / TILES, 1 / TILES], 4 * k);
    });
    const reach = this.bounds.center.length() + this.bounds.radius + 1;
    u.heightLow.value = -reach; u.heightRange.value = 2 * reach;
    this.atlas = new THREE.WebGLRenderTarget(ATLAS, ATLAS, { type: THREE.FloatType, format: THREE.RGBAFormat,
      minFilter: THREE.NearestFilter, magFilter: THREE.NearestFilter, depthBuffer: true });
    u.shadowAtlas = { value: this.atlas.texture };
    this.shadowMaterial = new THREE.ShaderMaterial({ glslVersion: THREE.GLSL3,
      uniforms: { lightDirection: { value: new THREE.Vector3() }, heightLow: u.heightLow, heightRange: u.heightRange },
      vertexShader: GLSL.SHADOW_VERTEX, fragmentShader: GLSL.SHADOW_FRAGMENT, side: THREE.DoubleSide });
    this.shadowRotation = null;
  }

  // One orthographic depth view per light, from its direction, framing the objects' bounding sphere (the ground
  // casts no shadow on what stands on it); redrawn only when the environment turns.
  updateShadows() {
    if (this.shadowRotation === this.state.rotation) return;
    const u = this.lightUniforms, R = this.rotation(), r = this.bounds.radius, e = u.shadowExtent.value;
    const r3 = this.renderer;
    r3.setRenderTarget(this.atlas);
    this.atlas.scissorTest = false;
    r3.setClearColor(0x000000, 0);
    r3.clear(true, true);
    const ground = this.meshes.filter((m) => m.userData.ground);
    ground.forEach((m) => { m.visible = false; });
    for (let k = 0; k < Math.min(this.lightCount, TILES * TILES); k++) {
      const d = new THREE.Vector3(...this.lightsDoc.lights[k].direction).applyMatrix3(R).normalize();
      const cam = new THREE.OrthographicCamera(-e / 2, e / 2, e / 2, -e / 2, 0.01, 4 * r + 1);
      cam.up.copy(Math.abs(d.y) < 0.99 ? new THREE.Vector3(0, 1, 0) : new THREE.Vector3(0, 0, -1));
      cam.position.copy(this.bounds.center).addScaledVector(d, 2 * r + 0.5);
      cam.lookAt(this.bounds.center);
      cam.updateMatrixWorld(true);
      const right = new THREE.Vector3().setFromMatrixColumn(cam.matrixWorld, 0);
      const up = new THREE.Vector3().setFromMatrixColumn(cam.matrixWorld, 1);
      u.lightRight.value.set(right.toArray(), 3 * k);
      u.lightUp.value.set(up.toArray(), 3 * k);
      const tile = ATLAS / TILES;
      this.atlas.viewport.set((k % TILES) * tile, Math.floor(k / TILES) * tile, tile, tile);
      this.atlas.scissor.copy(this.atlas.viewport);
      this.atlas.scissorTest = true;
      r3.setRenderTarget(this.atlas);
      this.shadowMaterial.uniforms.lightDirection.value.copy(d);
      this.scene.overrideMaterial = this.shadowMaterial;
      r3.render(this.scene, cam);
    }
    this.scene.overrideMaterial = null;
    ground.forEach((m) => { m.visible = true; });
    this.atlas.viewport.set(0, 0, ATLAS, ATLAS);
    this.atlas.scissorTest = false;
    this.shadowRotation = this.state.rotation;
  }

  // ---- RS-IBR synthesis ---------------------------------------------------------------------------------------------
  synthUniforms() {
    return { synthesised: { value: null }, synthFrame: this.synth.frame };
  }

  // The tessellated disc: vertices at every ``stride``-th destination texel centre (and the last), the quads that
  // reach the disc.
  discGeometry(size, stride) {
    // One more vertex beyond each side: the outermost texel centres then lie inside the mesh, not on its edge,
    // where the rasteriser's fill rule would drop half of them.
    const ticks = [-stride];
    for (let i = 0; i < size; i += stride) ticks.push(i);
    if (ticks[ticks.length - 1] !== size - 1) ticks.push(size - 1);
    ticks.push(size - 1 + stride);
    const pos = [], index = [], n = ticks.length;
    for (const j of ticks) for (const i of ticks) pos.push(((i + 0.5) / size) * 2 - 1, ((j + 0.5) / size) * 2 - 1, 0);
    const reach = 1 + 2.9 * stride / size;
    for (let j = 0; j < n - 1; j++) for (let i = 0; i < n - 1; i++) {
      const a = j * n + i, b = a + 1, c = a + n, d = c + 1;
      const near = [a, b, c, d].some((q) => Math.hypot(pos[3 * q], pos[3 * q + 1]) <= reach);
      if (near) index.push(a, b, d, a, d, c);
    }
    const g = new THREE.BufferGeometry();
    g.setAttribute("position", new THREE.Float32BufferAttribute(pos, 3));
    g.setIndex(index);
    return g;
  }

  // Synthesise brdf's radiance map for unit view v (the environment's frame) into a size² float target.
  synthesize(brdfIndex, v, stride = 1) {
    const brdf = this.brdfs[brdfIndex], part = brdf.part, size = part.maps.shape[1];
    const key = `${brdfIndex}/${stride}`;
    this.synthCache = this.synthCache || {};
    if (!this.synthCache[key]) {
      const target = new THREE.WebGLRenderTarget(size, size, { type: THREE.FloatType, format: THREE.RGBAFormat,
        minFilter: THREE.NearestFilter, magFilter: THREE.NearestFilter, depthBuffer: false });
      const uniforms = { ...this.shared, radianceMaps: { value: brdf.maps },
        mirrorWarp: { value: part.central === "mirror" }, destFrame: { value: new THREE.Matrix3() },
        destSize: { value: size }, sourceFrame: { value: [new THREE.Matrix3(), new THREE.Matrix3(), new THREE.Matrix3()] },
        sources: { value: [0, 0, 0] }, weights: { value: new THREE.Vector3() } };
      const mesh = new THREE.Mesh(this.discGeometry(size, stride), new THREE.ShaderMaterial({ glslVersion: THREE.GLSL3,
        uniforms, vertexShader: GLSL.COMMON + GLSL.SYNTH_VERTEX, fragmentShader: GLSL.COMMON + GLSL.SYNTH_FRAGMENT,
        depthTest: false, depthWrite: false, side: THREE.DoubleSide }));
      mesh.frustumCulled = false;
      const scene = new THREE.Scene(); scene.add(mesh);
      this.synthCache[key] = { target, uniforms, scene };
    }
    const s = this.synthCache[key];
    const { sources, weights } = blendWeights(part.views, part.triangles, v);
    s.uniforms.destFrame.value.copy(viewFrame(v));
    sources.forEach((k, j) => s.uniforms.sourceFrame.value[j].copy(rowsToMatrix3(part.frames[k])));
    s.uniforms.sources.value = sources.slice();
    s.uniforms.weights.value.set(...weights);
    this.renderer.setRenderTarget(s.target);
    this.renderer.setClearColor(0x000000, 0);
    this.renderer.clear(true, false);
    this.renderer.render(s.scene, this.screenCamera);
    return s;
  }

  // ---- three.js's own LightProbe -------------------------------------------------------------------------------------
  setupThree() {
    this.threeScene = new THREE.Scene();
    const group = new THREE.Group();
    group.matrixAutoUpdate = false;
    group.matrix.copy(TO_THREEJS);
    for (const m of this.meshes) {
      const color = new THREE.Color().setRGB(...m.userData.albedo.toArray(), THREE.LinearSRGBColorSpace);
      const copy = new THREE.Mesh(m.geometry, new THREE.MeshLambertMaterial({ color, side: THREE.DoubleSide }));
      copy.applyMatrix4(m.matrix);
      group.add(copy);
    }
    this.threeScene.add(group);
    this.threeProbe = new THREE.ObjectLoader().parse(this.threeDoc);
    if (!this.threeProbe.isLightProbe) throw new Error("threejs.json is not a LightProbe");
    this.threeCoefficients = this.threeProbe.sh.toArray();
    this.threeScene.add(this.threeProbe);
    this.threeRotation = 0;
  }

  threeCamera(camera) {  // the same view in three.js's panorama frame
    const c = camera.clone();
    c.matrixAutoUpdate = false;
    c.matrixWorld.multiplyMatrices(TO_THREEJS, camera.matrixWorld);
    c.matrix.copy(c.matrixWorld);
    c.matrixWorldInverse.copy(c.matrixWorld).invert();
    c.position.setFromMatrixPosition(c.matrixWorld);
    return c;
  }

  // ---- passes ---------------------------------------------------------------------------------------------------------
  setupScreens(background) {
    this.screenCamera = new THREE.OrthographicCamera(-1, 1, 1, -1, 0, 1);
    const quad = (fragment, uniforms) => {
      const m = new THREE.Mesh(new THREE.PlaneGeometry(2, 2), new THREE.ShaderMaterial({ glslVersion: THREE.GLSL3,
        uniforms, vertexShader: GLSL.SCREEN_VERTEX, fragmentShader: GLSL.COMMON + fragment,
        depthTest: false, depthWrite: false }));
      m.frustumCulled = false;
      const s = new THREE.Scene(); s.add(m);
      return { scene: s, uniforms };
    };
    this.backgroundPass = quad(GLSL.BACKGROUND_FRAGMENT, { ...this.shared, background: { value: background },
      inverseViewProjection: { value: new THREE.Matrix4() } });
    this.displayPass = quad(GLSL.DISPLAY_FRAGMENT, { hdr: { value: null }, exposure: { value: 1 },
      tonemap: { value: 0 } });
  }

  hdrTarget(w, h) {
    if (!this.hdr || this.hdr.width !== w || this.hdr.height !== h) {
      if (this.hdr) this.hdr.dispose();
      this.hdr = new THREE.WebGLRenderTarget(w, h, { type: THREE.FloatType, format: THREE.RGBAFormat,
        minFilter: THREE.NearestFilter, magFilter: THREE.NearestFilter, depthBuffer: true });
    }
    return this.hdr;
  }

  // Draw the current state from ``camera`` into ``target`` as linear radiance (alpha: 0 background, 1 objects,
  // 2 ground).
  renderHDR(target, camera) {
    const st = this.state, R = this.rotation();
    this.shared.envFromWorld.value.copy(R).transpose();
    this.shared.basisIndex.value = st.basis;
    this.lightUniforms.shadows.value = st.shadows;
    camera.updateMatrixWorld(true);
    if (st.method === "lights") this.updateShadows();
    if (st.method === "rsibr") {
      const eye = new THREE.Vector3().setFromMatrixPosition(camera.matrixWorld);
      const target0 = st.cameraTarget || this.controls.target;
      const v = eye.sub(target0).normalize().applyMatrix3(this.shared.envFromWorld.value).normalize();
      const s = this.synthesize(st.brdf, v, st.stride || 1);
      this.synth.frame.value.copy(viewFrame(v));
      this.synthTexture = s.target.texture;
    }
    const r = this.renderer;
    r.setRenderTarget(target);
    r.setClearColor(0x000000, 0);
    r.clear(true, true, true);
    if (st.background) {
      const vp = new THREE.Matrix4().multiplyMatrices(camera.projectionMatrix, camera.matrixWorldInverse);
      this.backgroundPass.uniforms.inverseViewProjection.value.copy(vp).invert();
      r.render(this.backgroundPass.scene, this.screenCamera);
    }
    if (st.method === "threejs") {
      if (this.threeRotation !== st.rotation) {
        const F = new THREE.Matrix3().setFromMatrix4(TO_THREEJS);
        const R3 = F.clone().multiply(R).multiply(F.clone().transpose());
        this.threeProbe.sh.fromArray(rotateSH9(this.threeCoefficients, R3));
        this.threeRotation = st.rotation;
      }
      r.render(this.threeScene, this.threeCamera(camera));
      return;
    }
    for (const m of this.meshes) {
      m.visible = !m.userData.ground || st.ground !== false;
      m.material = this.material(st.method, m);
      if (m.material.uniforms.synthesised) m.material.uniforms.synthesised.value = this.synthTexture;
    }
    r.render(this.scene, camera);
  }

  drawToCanvas() {
    const t0 = performance.now();
    const r = this.renderer, w = Math.max(1, this.canvas.clientWidth), h = Math.max(1, this.canvas.clientHeight);
    r.setPixelRatio(1);
    r.setSize(w, h, false);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    const hdr = this.hdrTarget(w, h);
    this.renderHDR(hdr, this.camera);
    this.display(hdr);
    const gl = r.getContext();
    gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(4));  // wait for the frame
    this.frameMs = performance.now() - t0;
    document.getElementById("readout").textContent =
      `${this.state.method}: ${METHODS[this.state.method]} · ${this.frameMs.toFixed(1)} ms/frame ` +
      `(${(1000 / this.frameMs).toFixed(1)} fps) · ${w}×${h}`;
  }

  display(hdr) {
    const u = this.displayPass.uniforms;
    u.hdr.value = hdr.texture;
    u.exposure.value = Math.pow(2, this.state.exposure);
    u.tonemap.value = TONEMAPS[this.state.tonemap];
    this.renderer.setRenderTarget(null);
    this.renderer.render(this.displayPass.scene, this.screenCamera);
  }

  requestFrame() {
    if (this.pending) return;
    this.pending = true;
    requestAnimationFrame(() => { this.pending = false; this.drawToCanvas(); });
  }

  // ---- the panel ------------------------------------------------------------------------------------------------------
  setupPanel() {
    const $ = (id) => document.getElementById(id);
    const method = $("method");
    for (const [k, text] of Object.entries(METHODS)) {
      if (GLOSSY.has(k) && !this.brdfs.length) continue;
      method.add(new Option(`${k} — ${text}`, k));
    }
    this.brdfs.forEach((b, i) => $("brdf").add(new Option(b.part.spec, String(i))));
    SH_NAMES.forEach((n, i) => $("basis").add(new Option(n, String(i))));
    const design = $("design");
    this.sliders = SH_NAMES.map((n, i) => {
      const row = document.createElement("label");
      const slider = Object.assign(document.createElement("input"), { type: "range", min: -3, max: 3, step: 0.05, value: 1 });
      const out = document.createElement("span");
      row.append(n.replace("Y", "L"), slider, out);
      design.append(row);
      const show = () => { out.textContent = Number(slider.value).toFixed(2); };
      slider.addEventListener("input", () => { this.state.design[i] = Number(slider.value); show(); this.updateCoefficients(); this.requestFrame(); });
      show();
      return { slider, show };
    });
    const bind = (id, key, parse = (x) => x, event = "input") => $(id).addEventListener(event, (e) => {
      this.state[key] = parse(e.target.type === "checkbox" ? e.target.checked : e.target.value);
      this.syncPanel(); this.requestFrame();
    });
    bind("method", "method", String, "change");
    bind("brdf", "brdf", Number, "change");
    bind("basis", "basis", Number, "change");
    bind("exposure", "exposure", Number);
    bind("tonemap", "tonemap", String, "change");
    bind("rotation", "rotation", Number);
    bind("background", "background", Boolean, "change");
    $("reset").addEventListener("click", () => { this.setState({ design: new Array(9).fill(1) }); });
    $("screenshot").addEventListener("click", () => {
      const a = Object.assign(document.createElement("a"), { href: this.screenshot(), download: `lightprobe-${this.state.method}.png` });
      a.click();
    });
    $("about").textContent = `${this.bake.source || "probe"} · ${this.meshes.length} meshes · ` +
      `${this.lightsDoc.lights.length} area lights · BRDFs: ${this.brdfs.map((b) => b.part.spec).join(", ") || "none"}`;
    this.syncPanel();
  }

  syncPanel() {
    const $ = (id) => document.getElementById(id);
    $("method").value = this.state.method;
    $("brdf").value = String(this.state.brdf);
    $("basis").value = String(this.state.basis);
    $("exposure").value = this.state.exposure;
    $("tonemap").value = this.state.tonemap;
    $("rotation").value = this.state.rotation;
    $("background").checked = this.state.background;
    $("brdf-row").style.display = GLOSSY.has(this.state.method) ? "" : "none";
    $("basis-row").style.display = this.state.method === "basis" ? "" : "none";
    this.sliders.forEach((s, i) => { s.slider.value = this.state.design[i]; s.show(); });
  }

  setState(changes) {
    Object.assign(this.state, changes);
    if (changes.design) this.updateCoefficients();
    if (changes.camera) this.resetCamera({ ...this.bake.camera, ...changes.camera });
    this.syncPanel();
    this.drawToCanvas();
  }

  screenshot() {
    this.drawToCanvas();
    return this.canvas.toDataURL("image/png");
  }
}

// ---- the page's API ---------------------------------------------------------------------------------------------------
function base64(floats) {
  const bytes = new Uint8Array(floats.buffer, floats.byteOffset, floats.byteLength);
  let s = "";
  for (let i = 0; i < bytes.length; i += 0x8000) s += String.fromCharCode.apply(null, bytes.subarray(i, i + 0x8000));
  return btoa(s);
}

function read(renderer, target) {
  const out = new Float32Array(target.width * target.height * 4);
  renderer.readRenderTargetPixels(target, 0, 0, target.width, target.height, out);
  return { width: target.width, height: target.height, rows: "bottom-up", rgba: base64(out) };
}

const viewer = new Viewer();
window.lightprobe = {
  viewer, methods: METHODS,
  // Linear radiance of one frame as the Python renderer's camera would take it: {method, brdf, camera:{eye, target,
  // up, fov}, width, height, background, rotation, design, shadows}.
  render(options) {
    const st = viewer.state, saved = { ...st, design: st.design.slice() };
    Object.assign(st, { background: false, rotation: 0, design: new Array(9).fill(1), shadows: true, ground: true,
      ...options });
    viewer.updateCoefficients();
    const c = { ...viewer.bake.camera, ...(options.camera || {}) };
    const cam = new THREE.PerspectiveCamera(c.fov, options.width / options.height, 0.01, 200);
    cam.up.set(...c.up); cam.position.set(...c.eye); cam.lookAt(new THREE.Vector3(...c.target));
    st.cameraTarget = new THREE.Vector3(...c.target);
    const target = new THREE.WebGLRenderTarget(options.width, options.height, { type: THREE.FloatType,
      format: THREE.RGBAFormat, minFilter: THREE.NearestFilter, magFilter: THREE.NearestFilter, depthBuffer: true });
    viewer.renderHDR(target, cam);
    const out = read(viewer.renderer, target);
    target.dispose();
    viewer.state = saved;
    delete viewer.state.cameraTarget;
    viewer.updateCoefficients();
    return out;
  },
  // The GPU-synthesised radiance map of BRDF ``brdf`` for unit ``view`` (world), read from its render target.
  synthesize({ brdf = 0, view, stride = 1 }) {
    const v = new THREE.Vector3(...view).normalize();
    return read(viewer.renderer, viewer.synthesize(brdf, v, stride).target);
  },
  // Milliseconds per frame (median of ``frames``) of ``method`` drawn to a width × height canvas, tone mapped.
  frameTime({ method, brdf = 0, width = 512, height = 512, frames = 5, ground = true }) {
    const saved = { ...viewer.state };
    Object.assign(viewer.state, { method, brdf, ground });
    viewer.canvas.style.width = `${width}px`; viewer.canvas.style.height = `${height}px`;
    viewer.canvas.parentElement.style.flex = "none";
    const times = [];
    for (let i = 0; i < frames + 1; i++) { viewer.drawToCanvas(); if (i) times.push(viewer.frameMs); }
    viewer.state = saved;
    times.sort((a, b) => a - b);
    return times[Math.floor(times.length / 2)];
  },
  setState: (changes) => viewer.setState(changes),
  screenshot: () => viewer.screenshot(),
};
viewer.init().then(() => { window.ready = true; }, (e) => { window.failed = String(e && e.stack || e); console.error(e); });
