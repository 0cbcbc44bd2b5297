// lightprobe's own GLSL: where the three papers' algorithms run. three.js draws the scene and loops; these shaders
// compute the lighting. Conventions (as the Python package): world frame +Y up, panorama front −Z, image right +X;
// every environment lookup first turns the world vector into the environment's frame (envFromWorld = Rᵀ for an
// environment turned by R, as EnvMap.rotated: light that came from d comes from R·d). Colours are linear radiance;
// the display pass alone applies exposure, tone mapping and sRGB.

export const COMMON = /* glsl */ `
precision highp sampler2DArray;
const float PI = 3.141592653589793;
uniform mat3 envFromWorld;

// Latlong texel lookup (world frame: u = atan2(x, −z)/2π + ½, v = acos(y)/π, row 0 at the top), bilinear by hand so
// float textures need no filtering extension and the seam wraps in u.
vec3 latlong(sampler2D t, vec3 d) {
  ivec2 size = textureSize(t, 0);
  vec2 uv = vec2(atan(d.x, -d.z) / (2.0 * PI) + 0.5, acos(clamp(d.y, -1.0, 1.0)) / PI);
  vec2 p = uv * vec2(size) - 0.5;
  ivec2 i0 = ivec2(floor(p));
  vec2 f = p - vec2(i0);
  int x0 = i0.x < 0 ? i0.x + size.x : (i0.x >= size.x ? i0.x - size.x : i0.x);
  int x1 = x0 + 1 >= size.x ? 0 : x0 + 1;
  int y0 = clamp(i0.y, 0, size.y - 1), y1 = clamp(i0.y + 1, 0, size.y - 1);
  vec3 a = mix(texelFetch(t, ivec2(x0, y0), 0).rgb, texelFetch(t, ivec2(x1, y0), 0).rgb, f.x);
  vec3 b = mix(texelFetch(t, ivec2(x0, y1), 0).rgb, texelFetch(t, ivec2(x1, y1), 0).rgb, f.x);
  return mix(a, b, f.y);
}

// Eq. 12/13 of Ramamoorthi & Hanrahan: E(n) = (n, 1)ᵀ M (n, 1), one matrix per channel, n in the environment frame.
uniform mat4 Mr, Mg, Mb;
vec3 irradianceSH(vec3 n) {
  vec4 h = vec4(n, 1.0);
  return vec3(dot(h, Mr * h), dot(h, Mg * h), dot(h, Mb * h));
}

// The nine real SH basis functions (no Condon–Shortley phase), lightprobe.sh's order and constants.
float basisSH(int i, vec3 d) {
  float x = d.x, y = d.y, z = d.z;
  if (i == 0) return 0.282095;
  if (i == 1) return 0.488603 * y;
  if (i == 2) return 0.488603 * z;
  if (i == 3) return 0.488603 * x;
  if (i == 4) return 1.092548 * x * y;
  if (i == 5) return 1.092548 * y * z;
  if (i == 6) return 0.315392 * (3.0 * z * z - 1.0);
  if (i == 7) return 1.092548 * x * z;
  return 0.546274 * (x * x - y * y);
}

// Sphere-map texels (Cabral et al.'s radiance maps): texel (i, j) covers [−1, 1]² cells; a texel is on the map
// when its square touches the disc (lightprobe.layouts.Sphere.valid_mask). Row 0 of a baked map is its top.
bool onDisc(ivec2 t, int n) {
  vec2 lo = vec2(t) / float(n) * 2.0 - 1.0, hi = vec2(t + 1) / float(n) * 2.0 - 1.0;
  vec2 c = clamp(vec2(0.0), lo, hi);
  return dot(c, c) < 1.0;
}

// The four taps of a bilinear read at texel position p (texel units, centres at +½) of a size² sphere map: texels
// off the disc (or off the map) weigh 0 and are clamped onto it, so the fetch stays in range.
void discTaps(vec2 p, int size, out ivec2 taps[4], out vec4 w) {
  ivec2 i0 = ivec2(floor(p - 0.5));
  vec2 f = p - 0.5 - vec2(i0);
  for (int k = 0; k < 4; k++) {
    ivec2 t = i0 + ivec2(k & 1, k >> 1);
    bool inside = t.x >= 0 && t.y >= 0 && t.x < size && t.y < size && onDisc(t, size);
    w[k] = inside ? ((k & 1) == 1 ? f.x : 1.0 - f.x) * ((k >> 1) == 1 ? f.y : 1.0 - f.y) : 0.0;
    taps[k] = clamp(t, ivec2(0), ivec2(size - 1));
  }
}
vec3 renormalised(vec3 sum, vec4 w) {
  float total = w.x + w.y + w.z + w.w;
  return total > 0.0 ? sum / total : sum;
}

// Bilinear read of layer k at the texel of local normal (n0, n1, ·), texels off the disc left out and the rest
// renormalised (lightprobe.rsibr._fetch); row 0 of a baked map is its top.
vec3 fetchArray(sampler2DArray maps, int k, vec2 n) {
  int size = textureSize(maps, 0).x;
  ivec2 t[4]; vec4 w;
  discTaps(vec2(n.x * 0.5 + 0.5, 0.5 - n.y * 0.5) * float(size), size, t, w);
  return renormalised(w.x * texelFetch(maps, ivec3(t[0], k), 0).rgb + w.y * texelFetch(maps, ivec3(t[1], k), 0).rgb
                    + w.z * texelFetch(maps, ivec3(t[2], k), 0).rgb + w.w * texelFetch(maps, ivec3(t[3], k), 0).rgb, w);
}
// The same of a synthesised map in a render target, whose row 0 is the bottom.
vec3 fetchTarget(sampler2D map, vec2 n) {
  int size = textureSize(map, 0).x;
  ivec2 t[4]; vec4 w;
  discTaps(vec2(n.x * 0.5 + 0.5, n.y * 0.5 + 0.5) * float(size), size, t, w);
  return renormalised(w.x * texelFetch(map, t[0], 0).rgb + w.y * texelFetch(map, t[1], 0).rgb
                    + w.z * texelFetch(map, t[2], 0).rgb + w.w * texelFetch(map, t[3], 0).rgb, w);
}

// lightprobe.radiance.view_frame: T = [right, up, v], up = +Y made perpendicular to v, or −Z near the poles.
mat3 viewFrame(vec3 v) {
  vec3 hint = abs(v.y) <= 0.99 ? vec3(0.0, 1.0, 0.0) : vec3(0.0, 0.0, -1.0);
  vec3 right = normalize(cross(hint, v));
  return mat3(right, cross(v, right), v);
}

float smoothFade(float x, float lo, float hi) {
  float t = clamp((x - lo) / (hi - lo), 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}
const float FADE_START = 0.1, FADE_END = 0.35, NORMAL_FADE = 0.1;  // lightprobe.rsibr's confidences

// The inverse warp into a source map of local frame T_k: the texel's local normal (xy) and its z, and the
// confidence (lightprobe.rsibr._blend).
vec4 warpInto(mat3 frameK, vec3 central, bool mirror) {
  vec3 c = transpose(frameK) * central;
  if (mirror) {
    vec3 h = c + vec3(0.0, 0.0, 1.0);
    float norm = length(h);
    vec3 n = norm < 1e-30 ? vec3(1.0, 0.0, 0.0) : h / norm;
    return vec4(n.xy, n.z, smoothFade(n.z, FADE_START, FADE_END));
  }
  return vec4(c.xy, c.z, smoothFade(c.z, 0.0, NORMAL_FADE));
}
`;

// ---- the objects -------------------------------------------------------------------------------------------------
export const OBJECT_VERTEX = /* glsl */ `
varying vec3 vWorld;
varying vec3 vNormal;
varying vec3 vVertexE;
void main() {
  vec4 world = modelMatrix * vec4(position, 1.0);
  vWorld = world.xyz;
  vNormal = normalize(mat3(modelMatrix) * normal);
#ifdef SH_VERTEX
  vVertexE = irradianceSH(envFromWorld * vNormal);  // the paper's hardware path: eq. 13 at the vertices
#endif
  gl_Position = projectionMatrix * viewMatrix * world;
}`;

export const OBJECT_FRAGMENT = /* glsl */ `
layout(location = 0) out highp vec4 outColor;
uniform vec3 albedo;
uniform float objectId;     // 1 objects, 2 the ground (read back by the tests)
uniform bool glossy;        // this surface has the chosen BRDF (the ground stays Lambertian)
uniform int basisIndex;
uniform sampler2D ambientMap;
varying vec3 vWorld;
varying vec3 vNormal;
varying vec3 vVertexE;

#ifdef LIGHTS
// Arbree et al.'s lights: each a cap of angular radius r around its direction, radiance L; unshadowed each adds
// E = L π sin²r max(n·d, 0); a shadow map per light (an atlas tile) holding the occluders' height along d gives the
// visible fraction by PCSS: blockers searched over the disc the cap covers at the tallest occluder, the penumbra
// from their mean height, then percentage-closer filtering over it.
#define MAX_LIGHTS 32  // the first 16 shadowed (atlas tiles), the rest unshadowed
uniform int lightCount;
uniform vec3 lightDir[MAX_LIGHTS];
uniform vec3 lightRadiance[MAX_LIGHTS];
uniform float lightRadius[MAX_LIGHTS];
uniform vec3 lightRight[MAX_LIGHTS];
uniform vec3 lightUp[MAX_LIGHTS];
uniform bool lightShadowed[MAX_LIGHTS];
uniform vec4 lightTile[MAX_LIGHTS];  // atlas offset (xy) and size (zw), in uv
uniform sampler2D shadowAtlas;
uniform vec3 shadowCentre;
uniform float shadowExtent;          // the tile's width in world units
uniform float heightLow, heightRange; // the atlas stores 1 + (h − low)/range, 0 where nothing is
uniform bool shadows;

float occluderHeight(int k, vec2 lateral) {  // lateral: world offset from the centre in (right, up)
  vec2 uv = lateral / shadowExtent + 0.5;
  if (any(lessThan(uv, vec2(0.0))) || any(greaterThan(uv, vec2(1.0)))) return -1e30;
  ivec2 size = textureSize(shadowAtlas, 0);
  vec2 p = (lightTile[k].xy + uv * lightTile[k].zw) * vec2(size);
  float s = texelFetch(shadowAtlas, ivec2(p), 0).r;
  return s < 0.5 ? -1e30 : heightLow + (s - 1.0) * heightRange;
}

vec2 vogel(int i, int n, float turn) {
  float r = sqrt((float(i) + 0.5) / float(n));
  float a = float(i) * 2.399963 + turn;
  return r * vec2(cos(a), sin(a));
}

float visibleFraction(int k, vec3 p, vec3 d) {
  float h = dot(p, d);
  vec2 lateral = vec2(dot(p - shadowCentre, lightRight[k]), dot(p - shadowCentre, lightUp[k]));
  float texel = shadowExtent / (float(textureSize(shadowAtlas, 0).x) * lightTile[k].z);
  float bias = 1.5 * texel;
  float t = tan(lightRadius[k]);
  float turn = 6.2831853 * fract(52.9829189 * fract(dot(gl_FragCoord.xy, vec2(0.06711056, 0.00583715))));
  float search = max((dot(shadowCentre, d) + 0.5 * shadowExtent - h) * t, texel);
  float blockers = 0.0, count = 0.0;
  for (int i = 0; i < 16; i++) {
    float hb = occluderHeight(k, lateral + search * vogel(i, 16, turn));
    if (hb > h + bias) { blockers += hb; count += 1.0; }
  }
  if (count == 0.0) return 1.0;
  float penumbra = max((blockers / count - h) * t, texel);
  float lit = 0.0;
  for (int i = 0; i < 32; i++) {
    float hb = occluderHeight(k, lateral + penumbra * vogel(i, 32, turn));
    lit += hb > h + bias ? 0.0 : 1.0;
  }
  return lit / 32.0;
}
#endif

#ifdef GLOSSY
uniform sampler2DArray radianceMaps;  // the BRDF's maps at the geodesic views (radiance)
uniform bool mirrorWarp;
#endif
#ifdef RSIBR_FRAME
uniform sampler2D synthesised;  // this frame's map, synthesised for the camera's view (a render target)
uniform mat3 synthFrame;
#endif
#ifdef RSIBR_PIXEL
uniform vec3 views[VIEWS];
uniform ivec3 triangles[TRIANGLES];
uniform vec3 edges[3 * TRIANGLES];  // a×b, b×c, c×a of each triangle: v is inside where all three v·(…) ≥ 0
float excess(vec3 a, vec3 b, vec3 c) {  // Van Oosterom & Strackee
  return 2.0 * atan(abs(dot(a, cross(b, c))), 1.0 + dot(a, b) + dot(b, c) + dot(c, a));
}
vec3 rsibrPerPixel(vec3 n, vec3 v) {
  vec3 central = mirrorWarp ? 2.0 * dot(n, v) * n - v : n;
  float best = -1e30; ivec3 tri = triangles[0];
  for (int i = 0; i < TRIANGLES; i++) {
    float m = min(min(dot(v, edges[3 * i]), dot(v, edges[3 * i + 1])), dot(v, edges[3 * i + 2]));
    if (m > best) { best = m; tri = triangles[i]; }
  }
  vec3 va = views[tri.x], vb = views[tri.y], vc = views[tri.z];
  vec3 w = vec3(excess(v, vb, vc), excess(va, v, vc), excess(va, vb, v));
  w /= max(w.x + w.y + w.z, 1e-30);
  vec3 total = vec3(0.0), fallback = vec3(0.0); float sum = 0.0, bestZ = -1e30;
  for (int j = 0; j < 3; j++) {
    int k = j == 0 ? tri.x : (j == 1 ? tri.y : tri.z);
    vec4 q = warpInto(viewFrame(views[k]), central, mirrorWarp);
    vec3 value = fetchArray(radianceMaps, k, q.xy);
    float c = w[j] * q.w;
    total += c * value; sum += c;
    if (q.z > bestZ) { bestZ = q.z; fallback = value; }
  }
  return sum > 1e-6 ? total / sum : fallback;
}
#endif
#ifdef SPLITSUM
uniform sampler2D prefiltered;  // the environment prefiltered with the GGX lobe of α (latlong, radiance)
uniform vec2 dfg[64];           // A, B at n·v = (i + ½)/64
uniform vec3 f0;
#endif

void main() {
  vec3 n = normalize(vNormal);
  vec3 v = normalize(cameraPosition - vWorld);
  if (!gl_FrontFacing) n = -n;
  vec3 ne = envFromWorld * n, ve = envFromWorld * v;
  vec3 color;
#if defined(SH_PIXEL)
  color = albedo * max(irradianceSH(ne), 0.0) / PI;
#elif defined(SH_VERTEX)
  color = albedo * max(gl_FrontFacing ? vVertexE : irradianceSH(ne), 0.0) / PI;
#elif defined(BASIS)
  float y = basisSH(basisIndex, ne) / 0.6;
  color = y > 0.0 ? vec3(y, 0.25 * y, 0.0) : vec3(0.0, 0.35 * -y, -y);
#elif defined(LIGHTS)
  vec3 e = latlong(ambientMap, ne);
  vec3 origin = vWorld + n * 0.002 * shadowExtent;
  for (int k = 0; k < MAX_LIGHTS; k++) {
    if (k >= lightCount) break;
    vec3 d = transpose(envFromWorld) * lightDir[k];  // the light's direction in the world
    float cosine = dot(n, d);
    if (cosine <= 0.0) continue;
    float s = sin(lightRadius[k]);
    float seen = (shadows && lightShadowed[k]) ? visibleFraction(k, origin, d) : 1.0;
    e += lightRadiance[k] * PI * s * s * cosine * seen;
  }
  color = albedo * e / PI;
#else
  // glossy methods: the chosen BRDF on the objects, the ground by eq. 13
  if (!glossy) {
    color = albedo * max(irradianceSH(ne), 0.0) / PI;
  } else {
  #if defined(RSIBR_FRAME)
    vec3 local = transpose(synthFrame) * ne;  // lightprobe.rsibr.map_at_normals
    float r = length(local.xy);
    if (local.z < 0.0 && r > 0.0) local.xy /= r;
    color = fetchTarget(synthesised, local.xy);
  #elif defined(RSIBR_PIXEL)
    color = rsibrPerPixel(ne, ve);
  #elif defined(SPLITSUM)
    float mu = clamp(dot(ne, ve), 0.0, 1.0);
    float x = clamp(mu * 64.0 - 0.5, 0.0, 63.0);
    int i = min(int(x), 62);
    vec2 ab = mix(dfg[i], dfg[i + 1], x - float(i));
    color = latlong(prefiltered, reflect(-ve, ne)) * (f0 * ab.x + ab.y);
  #endif
  }
#endif
  outColor = vec4(color, objectId);
}`;

// ---- RS-IBR synthesis on the GPU: the paper's algorithm ----------------------------------------------------------
// A tessellated disc drawn into the destination map's render target: each vertex sits at a destination texel
// centre, computes its central direction (normal, or mirror through the sphere map's g) in the world through the
// new view's frame, and its texel and confidence in each of the three source maps; the fragment reads each source
// at the interpolated texel and blends with the spherical barycentric weights (lightprobe.rsibr.synthesize).
export const SYNTH_VERTEX = /* glsl */ `
uniform mat3 destFrame;
uniform float destSize;
uniform mat3 sourceFrame[3];
uniform bool mirrorWarp;
varying vec2 vS0; varying vec2 vS1; varying vec2 vS2;
varying vec3 vZ; varying vec3 vConf;
void main() {
  vec2 xy = position.xy;
  float r = length(xy), limit = 1.0 - 1.0 / destSize;  // rim texels pulled in, as lightprobe.radiance.sphere_normals
  if (r > limit) xy *= limit / r;
  float z = sqrt(max(0.0, 1.0 - dot(xy, xy)));
  vec3 g = mirrorWarp ? vec3(2.0 * xy * z, 2.0 * z * z - 1.0) : vec3(xy, z);
  vec3 c = destFrame * g;
  vec4 a = warpInto(sourceFrame[0], c, mirrorWarp);
  vec4 b = warpInto(sourceFrame[1], c, mirrorWarp);
  vec4 d = warpInto(sourceFrame[2], c, mirrorWarp);
  vS0 = a.xy; vS1 = b.xy; vS2 = d.xy;
  vZ = vec3(a.z, b.z, d.z); vConf = vec3(a.w, b.w, d.w);
  gl_Position = vec4(position.xy, 0.0, 1.0);
}`;

export const SYNTH_FRAGMENT = /* glsl */ `
layout(location = 0) out highp vec4 outColor;
uniform sampler2DArray radianceMaps;
uniform ivec3 sources;
uniform vec3 weights;
uniform float destSize;
varying vec2 vS0; varying vec2 vS1; varying vec2 vS2;
varying vec3 vZ; varying vec3 vConf;
void main() {
  ivec2 texel = ivec2(gl_FragCoord.xy);
  if (!onDisc(texel, int(destSize))) { outColor = vec4(0.0); return; }
  vec3 a = fetchArray(radianceMaps, sources.x, vS0);
  vec3 b = fetchArray(radianceMaps, sources.y, vS1);
  vec3 d = fetchArray(radianceMaps, sources.z, vS2);
  vec3 c = weights * vConf;
  float sum = c.x + c.y + c.z;
  vec3 color;
  if (sum > 1e-6) color = (c.x * a + c.y * b + c.z * d) / sum;
  else color = vZ.x >= vZ.y && vZ.x >= vZ.z ? a : (vZ.y >= vZ.z ? b : d);
  outColor = vec4(color, 1.0);
}`;

// ---- the rest ------------------------------------------------------------------------------------------------------
export const SHADOW_VERTEX = /* glsl */ `
varying vec3 vWorld;
void main() {
  vec4 world = modelMatrix * vec4(position, 1.0);
  vWorld = world.xyz;
  gl_Position = projectionMatrix * viewMatrix * world;
}`;

export const SHADOW_FRAGMENT = /* glsl */ `
layout(location = 0) out highp vec4 outColor;
uniform vec3 lightDirection;
uniform float heightLow, heightRange;
varying vec3 vWorld;
void main() { outColor = vec4(1.0 + (dot(vWorld, lightDirection) - heightLow) / heightRange, 0.0, 0.0, 1.0); }`;

export const SCREEN_VERTEX = /* glsl */ `
varying vec2 vUv;
void main() { vUv = position.xy * 0.5 + 0.5; gl_Position = vec4(position.xy, 0.0, 1.0); }`;

export const BACKGROUND_FRAGMENT = /* glsl */ `
layout(location = 0) out highp vec4 outColor;
uniform sampler2D background;
uniform mat4 inverseViewProjection;
varying vec2 vUv;
void main() {
  vec4 far = inverseViewProjection * vec4(vUv * 2.0 - 1.0, 1.0, 1.0);
  vec4 near = inverseViewProjection * vec4(vUv * 2.0 - 1.0, -1.0, 1.0);
  vec3 d = normalize(far.xyz / far.w - near.xyz / near.w);
  outColor = vec4(latlong(background, envFromWorld * d), 0.0);
}`;

export const DISPLAY_FRAGMENT = /* glsl */ `
layout(location = 0) out highp vec4 outColor;
uniform sampler2D hdr;
uniform float exposure;
uniform int tonemap;  // 0 ACES (Narkowicz's fit), 1 Reinhard, 2 linear (clipped)
varying vec2 vUv;
vec3 srgb(vec3 c) { return mix(12.92 * c, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(0.0031308, c)); }
void main() {
  vec3 c = max(texelFetch(hdr, ivec2(gl_FragCoord.xy), 0).rgb, 0.0) * exposure;
  if (tonemap == 0) c = clamp((c * (2.51 * c + 0.03)) / (c * (2.43 * c + 0.59) + 0.14), 0.0, 1.0);
  else if (tonemap == 1) c = c / (1.0 + c);
  outColor = vec4(srgb(clamp(c, 0.0, 1.0)), 1.0);
}`;
