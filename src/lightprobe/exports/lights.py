"""Area lights + ambient SH for engines: each light as the engine's directional light, in its own units and frame.

Input: a :class:`~lightprobe.lights.lightsfile.LightSet` (world frame; each light's RGB ``power`` = ∫L dω over its cap
of angular radius r; the ambient as radiance SH). The conversions, each named once:

* :func:`perpendicular_irradiance` — a directional light's "intensity × colour" in every engine here is the
  irradiance E⊥ it gives a surface facing it; a diffuse surface then reflects albedo · E⊥ · max(n·l, 0) / π (three.js,
  Babylon, Filament and glTF's KHR_lights_punctual, whose lux is that irradiance). A uniform cap of radiance
  L = P/Ω gives E(n) = L π sin²r (n·d) wherever the whole cap is above the horizon, so E⊥ = P (1 + cos r)/2 makes the
  directional light exact there (only the normals whose horizon cuts the cap differ). Unity's built-in BRDF leaves
  out the 1/π, so its intensity is E⊥/π (as its ambient SH is E/π: :func:`lightprobe.exports.sh.unity_coefficients`).
* Directions: the engines want the direction the light *travels* (−d), stated in the same frame as each engine's
  SH export (:data:`lightprobe.exports.sh.DEFAULT_FRAMES`), so lights and ambient stay where the engine's background
  shows them.
* Colour and intensity: intensity = the largest channel of the engine's irradiance, colour = the channels over it
  (linear RGB in [0, 1]).
* Engines that take fewer lights (Filament: one directional light, the SUN) get the others folded into the ambient
  SH as uniform caps (:func:`cap_sh`, Funk–Hecke: exact in every band).
"""

from __future__ import annotations

import json
import math

import numpy as np

from ..util.errors import UsageError
from .sh import (babylon_polynomial, check_engine_values, export_threejs, filament_coefficients, gltf_coefficients,
                 unity_coefficients)
from ..maps.frames import BABYLON, FILAMENT, THREEJS, UNITY, WORLD, Frame
from ..lights.lightsfile import LightSet
from ..util.names import LIGHT_EXPORT_TARGETS
from ..sh.basis import SHCoeffs, basis, n_coeffs

# glTF nodes as Babylon's glTF loader places them: it turns the file's right-handed space into its left-handed one
# (its root node: z mirrored, then a half turn about +Y, i.e. (x, y, z) → (−x, y, z)); this frame makes a light in
# the file land where Babylon's frame (x, y, −z of world) has it, beside the EXT_lights_image_based ambient, which
# Babylon reads without any change of frame. Checked in Babylon itself by tests/test_engines.py.
GLTF_NODES = Frame("gltf-nodes", np.diag([-1.0, 1.0, -1.0]),
                   "glTF node space as Babylon's loader shows it beside EXT_lights_image_based: (−x, y, −z) of world")
FILAMENT_SUN_RADIUS_DEG = (0.25, 20.0)  # Filament clamps sunAngularRadius to this range
BABYLON_DEFAULT_LIGHTS = 4  # a Babylon material's maxSimultaneousLights unless raised


def perpendicular_irradiance(radius: float, power: np.ndarray) -> np.ndarray:
    """E⊥ of a uniform cap of angular ``radius`` and RGB ``power`` on a surface facing its centre: P (1 + cos r)/2.

    E⊥ is RGB irradiance (radiance × sr); a point light (r = 0) gives P.

    Parameters
    ----------
    radius : float
        The cap's angular radius r in radians (0 for a point light).
    power : numpy.ndarray
        (3,) the light's RGB power P = ∫L dω over its cap.

    Returns
    -------
    numpy.ndarray
        (3,) float64 E⊥, the irradiance (not divided by π) the cap gives a surface facing its centre.
    """
    return np.asarray(power, dtype=np.float64) * (1 + math.cos(radius)) / 2


def cap_sh(direction: np.ndarray, radius: float, power: np.ndarray, l_max: int) -> SHCoeffs:
    """Radiance SH (world frame, the paper's basis) of a uniform cap: radiance P/Ω within ``radius`` of ``direction``.

    Funk–Hecke: L_lm = L · 2π ∫_{cos r}^1 P_l(t) dt · Y_lm(d), with ∫_x^1 P_0 = 1 − x and
    ∫_x^1 P_l = (P_{l−1}(x) − P_{l+1}(x)) / (2l + 1). A cap of (nearly) no solid angle is a point light:
    L_lm = P Y_lm(d).

    Parameters
    ----------
    direction : numpy.ndarray
        (3,) the cap's centre d, a world-frame unit vector (+Y up, front −Z).
    radius : float
        The cap's angular radius r in radians.
    power : numpy.ndarray
        (3,) RGB power P = ∫L dω of the cap (radiance × sr).
    l_max : int
        The highest band, ≥ 0.

    Returns
    -------
    SHCoeffs
        Radiance coefficients ((l_max+1)², 3), world frame, no window.
    """
    from numpy.polynomial import legendre

    x = math.cos(radius)
    solid = 2 * math.pi * (1 - x)
    if solid <= 1e-12:  # a point light: 2π ∫ P_l / Ω → 1 (P_l(1) = 1), L_lm = P Y_lm(d)
        zonal = np.ones(l_max + 1)
    else:
        p = [legendre.legval(x, [0] * l + [1]) for l in range(l_max + 2)]
        zonal = np.array([1 - x] + [(p[l - 1] - p[l + 1]) / (2 * l + 1) for l in range(1, l_max + 1)])
        zonal *= 2 * math.pi / solid
    scale = np.asarray(power, dtype=np.float64)
    y = basis(l_max, np.asarray(direction, dtype=np.float64)[None, :])[0]  # (n_coeffs,)
    bands = np.repeat(np.arange(l_max + 1), 2 * np.arange(l_max + 1) + 1)
    return SHCoeffs((zonal[bands] * y)[:, None] * scale[None, :], WORLD, "radiance")


def ambient_sh(lights: LightSet, folded: list[int], l_max: int = 2) -> SHCoeffs:
    """The ambient's radiance SH (bands ≤ ``l_max``; zero if the file has none) plus the lights ``folded`` into it.

    Parameters
    ----------
    lights : LightSet
        The lights file's lights and ambient (world frame); an ambient must be of order ≥ ``l_max``.
    folded : list of int
        Indices of the lights to add to the ambient as uniform caps (:func:`cap_sh`).
    l_max : int, default 2
        The highest band of the result.

    Returns
    -------
    SHCoeffs
        Radiance coefficients ((l_max+1)², 3) in the world frame.
    """
    total = np.zeros((n_coeffs(l_max), 3))
    with np.errstate(over="ignore", invalid="ignore"):  # too large a sum is refused by the engine's conversion
        if lights.ambient is not None:
            total += lights.ambient.truncated(min(l_max, lights.ambient.l_max)).to_frame(WORLD).coeffs[:n_coeffs(l_max)]
        for i in folded:
            total += cap_sh(lights.directions[i], lights.radii[i], lights.powers[i], l_max).coeffs
    return SHCoeffs(total, WORLD, "radiance")


def _colour_intensity(e: np.ndarray) -> tuple[list[float], float]:
    peak = float(e.max())
    return ([float(v) for v in (e / peak if peak > 0 else np.ones(3))], peak)


def engine_lights(lights: LightSet, frame: Frame, over_pi: bool = False) -> list[dict]:
    """Each light as an engine's directional light, in ``frame``, brightest first.

    Each is a dict: ``travel`` (unit, the direction the light travels, in ``frame``), ``toward`` (its opposite:
    where the light is), ``colour`` (linear RGB, max 1), ``intensity`` (E⊥, or E⊥/π with ``over_pi``) and
    ``angular_radius_deg``.

    Parameters
    ----------
    lights : LightSet
        The lights (world frame, RGB power ∫L dω, angular radius in radians).
    frame : Frame
        The engine's frame, in which ``travel`` and ``toward`` are stated.
    over_pi : bool, default False
        Give E⊥/π (Unity, whose BRDF leaves out the 1/π) instead of E⊥.

    Returns
    -------
    list of dict
        One dict a light (lists of floats for the vectors and the colour, floats for the intensity and the radius
        in degrees), sorted by intensity, largest first; a light with no power has colour (1, 1, 1) and
        intensity 0.

    Raises
    ------
    InputError
        A light's intensity is too large for an engine's 32-bit floats
        (:func:`lightprobe.exports.sh.check_engine_values`).
    """
    out = []
    for d, r, p in zip(lights.directions, lights.radii, lights.powers):
        e = check_engine_values(perpendicular_irradiance(r, p) / (math.pi if over_pi else 1.0), "a light's intensity")
        colour, intensity = _colour_intensity(e)
        toward = frame.from_world(d)
        out.append({"travel": [float(-v) for v in toward], "toward": [float(v) for v in toward], "colour": colour,
                    "intensity": intensity, "angular_radius_deg": math.degrees(float(r))})
    return sorted(out, key=lambda light: -light["intensity"] * max(light["colour"]))


def _brightest(lights: LightSet) -> list[int]:
    return sorted(range(len(lights.radii)), key=lambda i: -float(perpendicular_irradiance(lights.radii[i],
                                                                                          lights.powers[i]).max()))


# ---- the engines --------------------------------------------------------------------------------------------------
def export_threejs_lights(lights: LightSet, frame: Frame = THREEJS) -> str:
    """A three.js ObjectLoader JSON ``Group``: the ambient as a ``LightProbe`` and one ``DirectionalLight`` a light.

    The ``LightProbe`` is as :func:`lightprobe.exports.sh.export_threejs` writes it. Each ``DirectionalLight`` is
    placed 10 units toward the light with its target at the origin (three.js lights along position − target).
    ``color`` is the sRGB hex three.js's ``Color`` decodes to the linear colour (8 bits a channel: ≤ 0.4 % off);
    ``userData`` holds the exact linear colour. Intensity: E⊥ (three.js's lux since r155: its Lambert term divides
    by π).

    Parameters
    ----------
    lights : LightSet
        The lights and the ambient's radiance SH (world frame), from
        :func:`lightprobe.lights.lightsfile.read_lights_json`.
    frame : Frame, default THREEJS
        The frame of the lights' positions and of the probe's SH; the default is the frame three.js shows an
        equirectangular background in.

    Returns
    -------
    str
        The JSON text of the ``Group`` (probe first, then the lights, brightest first).
    """
    probe = json.loads(export_threejs(ambient_sh(lights, []), frame))["object"]
    children = [probe]
    for k, light in enumerate(engine_lights(lights, frame)):
        children.append({"uuid": f"5b0c0f0e-1a1b-4c2d-8e3f-{k + 2:012d}", "type": "DirectionalLight",
                         "name": f"lightprobe light {k + 1}", "layers": 1,
                         "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, *[10 * v for v in light["toward"]], 1],
                         "up": [0, 1, 0], "color": _srgb_hex(light["colour"]), "intensity": light["intensity"],
                         "userData": {"linearColor": light["colour"],
                                      "angularRadiusDeg": light["angular_radius_deg"]}})
    return json.dumps({"metadata": {"version": 4.6, "type": "Object", "generator": "lightprobe"},
                       "object": {"uuid": "5b0c0f0e-1a1b-4c2d-8e3f-000000000000", "type": "Group",
                                  "name": "lightprobe lights + ambient (three.js frame)", "layers": 1,
                                  "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1], "up": [0, 1, 0],
                                  "children": children}}, indent=1, allow_nan=False)


def _srgb_hex(colour: list[float]) -> int:
    c = np.clip(np.asarray(colour), 0, 1)
    encoded = np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)
    r, g, b = (int(round(255 * v)) for v in encoded)
    return (r << 16) | (g << 8) | b


def export_filament_lights(lights: LightSet, frame: Frame = FILAMENT) -> str:
    """Filament takes one directional light: the brightest as the SUN; every other light is folded into the ambient.

    The brightest becomes ``LightManager::Type::SUN`` (``direction`` = travel, ``intensity`` E⊥ in lux with the
    IndirectLight at intensity 1, linear ``color``, ``sunAngularRadius`` the cap's radius in degrees within
    Filament's 0.25°–20°); every other light is folded into the ambient, whose ``irradiance`` table
    (IndirectLight::Builder::irradiance(3, sh)) is :func:`lightprobe.exports.sh.filament_coefficients` of it.

    Parameters
    ----------
    lights : LightSet
        The file's lights (world frame): the brightest by E⊥ becomes the sun, the rest join the ambient SH.
    frame : Frame, default FILAMENT
        The frame of the sun's direction and of the irradiance table (Filament's: the world frame).

    Returns
    -------
    str
        JSON with ``frame``, ``indirectLightIntensity`` 1, ``irradiance`` (nine RGB rows, K_i Â_l L_lm / π),
        ``folded_into_irradiance`` (how many lights) and ``sun`` (absent when there is no light).
    """
    order = _brightest(lights)
    sun = engine_lights(LightSet(lights.directions[order[:1]], lights.radii[order[:1]], lights.powers[order[:1]],
                                 None, lights.method), frame) if order else []
    sh = filament_coefficients(ambient_sh(lights, order[1:]), frame)
    doc = {"format": "lightprobe.filament-lights", "frame": frame.name, "indirectLightIntensity": 1.0,
           "irradiance": [[float(v) for v in row] for row in sh], "folded_into_irradiance": len(order[1:])}
    if sun:
        lo, hi = FILAMENT_SUN_RADIUS_DEG
        doc["sun"] = {"type": "SUN", "direction": sun[0]["travel"], "color": sun[0]["colour"],
                      "intensity": sun[0]["intensity"],
                      "sunAngularRadius": min(hi, max(lo, sun[0]["angular_radius_deg"]))}
    return json.dumps(doc, indent=1, allow_nan=False)


def export_babylon_lights(lights: LightSet, frame: Frame = BABYLON) -> str:
    """Babylon: a ``DirectionalLight`` per light and the ambient as a ``SphericalPolynomial``.

    Each light is for ``new DirectionalLight(name, Vector3.FromArray(direction), scene)`` (``direction`` = travel
    in Babylon's frame), ``intensity`` E⊥ (its PBR Lambert term divides by π), ``diffuse`` the linear colour; the
    ambient is the ``SphericalPolynomial`` of :func:`lightprobe.exports.sh.export_babylon`. A Babylon material
    takes 4 lights unless its ``maxSimultaneousLights`` is raised: ``maxSimultaneousLights`` says how many.

    Parameters
    ----------
    lights : LightSet
        Read from a lights file (world frame): every light becomes a Babylon light, none is folded.
    frame : Frame, default BABYLON
        The frame of the directions and of the polynomial: Babylon's left-handed default, (x, y, −z) of world.

    Returns
    -------
    str
        JSON with ``frame``, ``directionalLights`` (brightest first), ``maxSimultaneousLights`` (at least 4) and
        ``polynomial`` (nine RGB rows, order x, y, z, xx, yy, zz, yz, zx, xy).
    """
    poly = babylon_polynomial(ambient_sh(lights, []), frame)
    out = [{"name": f"lightprobe light {k + 1}", "direction": light["travel"], "intensity": light["intensity"],
            "diffuse": light["colour"], "angularRadiusDeg": light["angular_radius_deg"]}
           for k, light in enumerate(engine_lights(lights, frame))]
    return json.dumps({"format": "lightprobe.babylon-lights", "frame": frame.name, "directionalLights": out,
                       "maxSimultaneousLights": max(BABYLON_DEFAULT_LIGHTS, len(out)),
                       "polynomial": [[float(v) for v in poly[k]] for k in ("x", "y", "z", "xx", "yy", "zz", "yz",
                                                                             "zx", "xy")]}, indent=1, allow_nan=False)


def export_unity_lights(lights: LightSet, frame: Frame = UNITY) -> str:
    """A C# method making one directional ``Light`` a light and setting ``RenderSettings.ambientProbe``.

    Each ``Light`` (``LightType.Directional``) gets ``transform.rotation = Quaternion.LookRotation(travel)`` (a
    Unity light shines along its +Z), linear ``color`` and ``intensity`` E⊥/π (Unity's BRDF leaves out the 1/π);
    ``RenderSettings.ambientProbe`` is set to the ambient (:func:`lightprobe.exports.sh.unity_coefficients`).
    Needs a linear-colour-space project.

    Parameters
    ----------
    lights : LightSet
        Area lights and ambient as the lights file gives them; the ambient's bands ≤ 2 fill the probe.
    frame : Frame, default UNITY
        The frame of the directions and of the SH: Unity's left-handed frame, (x, y, −z) of world.

    Returns
    -------
    str
        C# source of the static class ``LightprobeLights`` whose ``Apply()`` does the above.
    """
    sh = unity_coefficients(ambient_sh(lights, []), frame)
    lines = [f"        sh[{ch}, {i}] = {sh[i, ch]:.9g}f;" for ch in range(3) for i in range(9)]
    for k, light in enumerate(engine_lights(lights, frame, over_pi=True)):
        t, c = light["travel"], light["colour"]
        lines += [f"        var light{k} = new GameObject(\"lightprobe light {k + 1}\").AddComponent<Light>();",
                  f"        light{k}.type = LightType.Directional;",
                  f"        light{k}.transform.rotation = Quaternion.LookRotation(new Vector3({t[0]:.9g}f, "
                  f"{t[1]:.9g}f, {t[2]:.9g}f));",
                  f"        light{k}.color = new Color({c[0]:.9g}f, {c[1]:.9g}f, {c[2]:.9g}f);",
                  f"        light{k}.intensity = {light['intensity']:.9g}f;"]
    return ("// lightprobe export: area lights as directional lights + ambient SH for Unity (left-handed, +Y up,\n"
            "// +Z forward; linear colour space). Intensities are E_perp / pi, as Unity's BRDF leaves out 1/pi.\n"
            "using UnityEngine;\nusing UnityEngine.Rendering;\n\npublic static class LightprobeLights\n{\n"
            "    public static void Apply()\n    {\n        var sh = new SphericalHarmonicsL2();\n"
            + "\n".join(lines) + "\n        RenderSettings.ambientMode = AmbientMode.Custom;\n"
            "        RenderSettings.ambientProbe = sh;\n    }\n}\n")


def gltf_lights(lights: LightSet, specular_size: int = 32) -> tuple[dict, list[bytes]]:
    """A glTF 2.0 document and its images: ``KHR_lights_punctual`` directional lights and the ambient as IBL.

    The lights (``intensity`` E⊥ in lux, linear ``color``) sit each on a node whose ``rotation`` turns the light's
    −Z onto its travel direction in :data:`GLTF_NODES`; the ambient is the scene's ``EXT_lights_image_based`` light
    (:func:`lightprobe.exports.containers.gltf_ibl`): ``irradianceCoefficients`` of its SH, and — the file has no
    map — its specular cube prefiltered from the ambient radiance the SH describes (clamped at 0; smooth, as an
    ambient is).

    Parameters
    ----------
    lights : LightSet
        The lights and the ambient's radiance SH (world frame); with no ambient the specular cube is black.
    specular_size : int, default 32
        The specular cube's face edge in texels: a power of two, at most 1024.

    Returns
    -------
    document : dict
        The glTF document, its ``images`` without data yet.
    images : list of bytes
        The specular cube's PNGs in the order of the document's ``images``: write both with
        :func:`lightprobe.exports.containers.glb` or :func:`lightprobe.exports.containers.gltf_embedded`.

    Raises
    ------
    UsageError
        ``specular_size`` is not a power of two up to 1024.
    InputError
        A light's intensity or the ambient is too large for glTF's 32-bit floats.
    """
    from .containers import gltf_ibl
    from ..maps import EnvMap
    from ..maps.layouts import LATLONG

    grid = LATLONG.grid_shape(32)
    engine_lights(lights, GLTF_NODES)  # lights, or an ambient, too large for glTF: refused before the cube
    gltf_coefficients(ambient_sh(lights, []))
    if lights.ambient is not None:
        with np.errstate(over="ignore", invalid="ignore"):
            radiance = np.maximum(lights.ambient.to_frame(WORLD).evaluate(LATLONG.directions(grid)), 0.0)
        radiance = np.minimum(radiance, np.finfo(np.float32).max)
    else:
        radiance = np.zeros(grid + (3,))
    document, images = gltf_ibl(EnvMap(radiance.astype(np.float32), LATLONG), ambient_sh(lights, []), specular_size)
    return add_gltf_lights(document, lights), images


def add_gltf_lights(document: dict, lights: LightSet) -> dict:
    """Add the lights to a glTF document as ``KHR_lights_punctual`` directional lights, one node each.

    Each light's ``intensity`` is E⊥ in lux and its ``color`` linear; its node's ``rotation`` turns the light's −Z
    onto its travel direction in :data:`GLTF_NODES`; the nodes become the first scene's ``nodes``.

    Parameters
    ----------
    document : dict
        A glTF 2.0 document with ``extensionsUsed``, ``extensions`` and ``scenes`` (as
        :func:`lightprobe.exports.containers.gltf_ibl` makes it); changed in place.
    lights : LightSet
        The lights (world frame).

    Returns
    -------
    dict
        ``document``, with the lights.

    Raises
    ------
    InputError
        A light's intensity is too large for glTF's 32-bit floats.
    """
    found = engine_lights(lights, GLTF_NODES)
    document["extensionsUsed"].append("KHR_lights_punctual")
    document["extensions"]["KHR_lights_punctual"] = {"lights": [
        {"type": "directional", "name": f"lightprobe light {k + 1}", "color": light["colour"],
         "intensity": light["intensity"]} for k, light in enumerate(found)]}
    document["nodes"] = [{"name": f"lightprobe light {k + 1}", "rotation": _quaternion_from_minus_z(light["travel"]),
                          "extensions": {"KHR_lights_punctual": {"light": k}}} for k, light in enumerate(found)]
    document["scenes"][0]["nodes"] = list(range(len(found)))
    return document


def _quaternion_from_minus_z(travel) -> list[float]:
    """The unit quaternion [x, y, z, w] turning −Z onto unit ``travel`` (the shortest turn; a half turn about +Y
    when travel is +Z)."""
    a, b = np.array([0.0, 0.0, -1.0]), np.asarray(travel, dtype=np.float64)
    c = float(a @ b)
    if c < -1 + 1e-12:
        return [0.0, 1.0, 0.0, 0.0]
    axis = np.cross(a, b)
    q = np.array([*axis, 1.0 + c])
    q /= np.linalg.norm(q)
    return [float(v) for v in q]


def export_lights(lights: LightSet, target: str) -> str:
    """The lights file for ``target`` (:data:`lightprobe.util.names.LIGHT_EXPORT_TARGETS`), in the target's frame.

    glTF is not text: use :func:`gltf_lights`, written with :func:`lightprobe.exports.containers.glb` or
    ``gltf_embedded``.

    Parameters
    ----------
    lights : LightSet
        The lights and the ambient's radiance SH (world frame), from
        :func:`lightprobe.lights.lightsfile.read_lights_json`.
    target : str
        ``threejs``, ``filament``, ``babylon`` or ``unity``.

    Returns
    -------
    str
        The file's text, as :func:`export_threejs_lights`, :func:`export_filament_lights`,
        :func:`export_babylon_lights` or :func:`export_unity_lights` writes it with its default frame.

    Raises
    ------
    UsageError
        ``target`` is not one of those four (``gltf`` included).
    """
    writers = {"threejs": export_threejs_lights, "filament": export_filament_lights,
               "babylon": export_babylon_lights, "unity": export_unity_lights}
    if target not in writers:
        raise UsageError(f"lights export to {target!r} is not known as text; choose {', '.join(writers)} (gltf: "
                         "gltf_lights)")
    return writers[target](lights)
