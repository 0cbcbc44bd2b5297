"""Godot 4: a scene (``environment.tscn``) whose ``WorldEnvironment`` shows the probe as its sky and lights with it,
and one ``DirectionalLight3D`` per light found.

Godot imports no prefiltered environment: it filters its sky into its own radiance cube on the GPU whenever the
sky changes. What a bake can give it is the panorama in Godot's own mapping, so nothing is mirrored or turned, and
the lights. Godot's sky shaders read a panorama at SKY_COORDS = (atan2(x, −z)/2π wrapped into [0, 1), acos(y)/π)
(its sky.glsl): −Z at the image's left edge, +X a quarter in, +Z at the centre, +Y at the top. lightprobe's lat-long
has −Z at the centre, so Godot's panorama is it turned by half its width. Godot's frame is the world frame (right-
handed, +Y up); a ``DirectionalLight3D`` shines along its −Z, and without physical light units Godot multiplies its
``light_energy`` by π before a Lambert term that divides by π: ``light_energy`` = E⊥/π. Its ``light_color`` is
sRGB-encoded (Godot decodes it to linear before shading).

With lights, the scene's sky shader shows the whole probe as the background but lights with the ambient remainder
(``AT_CUBEMAP_PASS``: the pass that makes Godot's radiance cube), so the lights are not counted twice.
"""

from __future__ import annotations

import numpy as np

from ...maps.frames import WORLD
from ...maps.layouts import LATLONG
from ..folder import EngineFolder
from ..source import BakeSource
from .common import manifest_extra

FRAME = WORLD
ENCODINGS = ()

SKY_SHADER = """shader_type sky;
// lightprobe: the background shows the whole probe; the radiance cube Godot lights with (AT_CUBEMAP_PASS) is the
// ambient remainder, the lights being DirectionalLight3D nodes of the scene.
uniform sampler2D probe : source_color, filter_linear, hint_default_black;
uniform sampler2D ambient : source_color, filter_linear, hint_default_black;

void sky() {
	COLOR = AT_CUBEMAP_PASS ? texture(ambient, SKY_COORDS).rgb : texture(probe, SKY_COORDS).rgb;
}
"""


def godot_panorama(env_latlong: np.ndarray) -> np.ndarray:
    """lightprobe's lat-long pixels in Godot's panorama mapping: turned by half the width.

    Parameters
    ----------
    env_latlong : numpy.ndarray
        (H, 2H, 3) lat-long radiance, world frame (centre −Z).

    Returns
    -------
    numpy.ndarray
        The same pixels with −Z at the left edge (Godot's SKY_COORDS).
    """
    return np.roll(env_latlong, env_latlong.shape[1] // 2, axis=1)


def light_basis(toward) -> np.ndarray:
    """The rotation whose −Z column is the light's travel (its +Z points toward the light).

    Parameters
    ----------
    toward : sequence of float
        Unit direction toward the light, world frame.

    Returns
    -------
    numpy.ndarray
        (3, 3) orthonormal, right-handed; columns are the node's local X, Y, Z axes.
    """
    z = np.asarray(toward, dtype=np.float64)
    z = z / np.linalg.norm(z)
    up = np.array([0.0, 1.0, 0.0]) if abs(z[1]) < 0.99 else np.array([1.0, 0.0, 0.0])
    x = np.cross(up, z)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z], axis=1)


def srgb_encode(linear) -> list[float]:
    """Linear RGB in [0, 1] as the sRGB-encoded ``Color`` Godot stores for a light (it decodes it with the
    piecewise sRGB curve before shading).

    Parameters
    ----------
    linear : sequence of float
        Linear RGB, each in [0, 1].

    Returns
    -------
    list of float
        The sRGB-encoded channels.
    """
    c = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
    return [float(v) for v in np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)]


def _transform(basis: np.ndarray, origin=(0.0, 0.0, 0.0)) -> str:
    # Godot's text format lists the basis row by row (Basis(xx, xy, xz, yx, …) sets rows), then the origin
    values = [*basis.reshape(-1), *origin]
    return "Transform3D(" + ", ".join(f"{v:.9g}" for v in values) + ")"


def bake(source: BakeSource, folder: EngineFolder) -> dict:
    """Write ``sky.exr`` and the scene ``environment.tscn`` (with lights: ``ambient.exr`` and ``sky.gdshader``).

    Parameters
    ----------
    source : BakeSource
        The bake's working form.
    folder : EngineFolder
        Godot's folder.

    Returns
    -------
    dict
        The manifest's ``accuracy`` (what an SH9 ambient would be off by: Godot filters its own) and, with lights,
        ``lights``.
    """
    rows = source.options.skybox_size
    mapping = "Godot panorama: −Z at the left edge, +X a quarter in, +Y at the top (lat-long turned by half)"
    folder.add_image("sky.exr", godot_panorama(source.env.to(LATLONG, rows).data), "skybox+environment",
                     "radiance", layout="godot-panorama", size=[2 * rows, rows], mapping=mapping)
    # Godot filters its own sky from the whole probe: the SH measured is the probe's
    extra = manifest_extra(source, lights_frame=FRAME, over_pi=True, whole_probe=True)
    lights = extra.get("lights", [])
    if source.options.lights:
        ambient = source.decomposition().ambient
        folder.add_image("ambient.exr", godot_panorama(ambient.to(LATLONG, min(rows, 256)).data), "environment",
                         "radiance (the probe without its lights)", layout="godot-panorama",
                         size=[2 * min(rows, 256), min(rows, 256)], mapping=mapping)
        folder.add_text("sky.gdshader", SKY_SHADER, "sky shader", "none", "Godot shading language")
    folder.add_text("environment.tscn", _scene(lights), "scene", "light_energy = E⊥/π", "Godot 4 text scene")
    return extra


def _scene(lights: list[dict]) -> str:
    resources = ['[ext_resource type="Texture2D" path="sky.exr" id="1_sky"]']
    if lights:
        resources += ['[ext_resource type="Texture2D" path="ambient.exr" id="2_ambient"]',
                      '[ext_resource type="Shader" path="sky.gdshader" id="3_shader"]',
                      '[sub_resource type="ShaderMaterial" id="SkyMaterial_1"]\nshader = ExtResource("3_shader")\n'
                      'shader_parameter/probe = ExtResource("1_sky")\n'
                      'shader_parameter/ambient = ExtResource("2_ambient")']
    else:
        resources += ['[sub_resource type="PanoramaSkyMaterial" id="SkyMaterial_1"]\npanorama = ExtResource("1_sky")']
    resources += ['[sub_resource type="Sky" id="Sky_1"]\nsky_material = SubResource("SkyMaterial_1")',
                  # background: sky (2); ambient light: sky (3); reflections: sky (2)
                  '[sub_resource type="Environment" id="Environment_1"]\nbackground_mode = 2\nsky = SubResource("Sky_1")\n'
                  'ambient_light_source = 3\nreflected_light_source = 2']
    nodes = ['[node name="LightprobeEnvironment" type="Node3D"]',
             '[node name="WorldEnvironment" type="WorldEnvironment" parent="."]\nenvironment = SubResource("Environment_1")']
    for k, light in enumerate(lights):
        c = srgb_encode(light["colour"])
        nodes.append(f'[node name="LightprobeLight{k + 1}" type="DirectionalLight3D" parent="."]\n'
                     f'transform = {_transform(light_basis(light["toward"]))}\n'
                     f'light_color = Color({c[0]:.9g}, {c[1]:.9g}, {c[2]:.9g}, 1)\n'
                     f'light_energy = {light["intensity"]:.9g}\nshadow_enabled = true')
    steps = len(resources) + 1
    return f"[gd_scene load_steps={steps} format=3]\n\n" + "\n\n".join(resources + nodes) + "\n"


def usage(folder: EngineFolder) -> str:
    """How to use the folder in Godot 4.

    Parameters
    ----------
    folder : EngineFolder
        Godot's folder, its files written.

    Returns
    -------
    str
        Markdown.
    """
    return ("# Godot 4\n\nCopy the folder into the project (say `res://lightprobe/`) and instance "
            "`environment.tscn` in the main scene, or drag it in. Its `WorldEnvironment` shows the probe as the sky "
            "and takes ambient light and reflections from it (Godot filters its own radiance cube from the sky); "
            "each light found is a `DirectionalLight3D` with shadows on (`light_energy` = E⊥/π, physical light "
            "units off).\n\n```gdscript\nvar env := preload(\"res://lightprobe/environment.tscn\").instantiate()\n"
            "add_child(env)\n```\n\nGodot imports no prefiltered environment, so none is written: `sky.exr` is the "
            "panorama in Godot's own mapping (−Z at the left edge), not the lat-long other tools use.\n")
