"""The names users type — layouts, frames, windows, tone curves, export targets, render methods — in a module that
imports nothing, so the command line can list them (``--help``, argument checking) without loading numpy.

Each module that implements a set of names takes its tuple from here and builds its table from it;
``tests/test_project.py`` checks that every table has exactly these names, in this order.
"""

LAYOUTS = ("latlong", "angular", "sphere", "cube", "cross", "hcross")
FRAMES = ("world", "rh2001", "threejs", "threejs-axes", "filament", "gltf", "unity", "babylon")
WINDOWS = ("none", "hanning", "lanczos", "auto")
CURVES = ("srgb", "aces")
EXPORT_TARGETS = ("json", "threejs", "filament", "unity", "gltf", "babylon", "glsl")
GLTF_SCALINGS = ("irradiance", "pi-radiance")
RENDER_METHODS = ("sh", "brute", "hybrid", "lights", "mediancut", "varmin", "direct", "rsibr", "splitsum")
LIGHT_EXPORT_TARGETS = ("threejs", "filament", "unity", "gltf", "babylon")
LIGHT_METHODS = ("arbree2005", "mediancut", "varmin")
# Engines 'lightprobe bake --for' writes a folder for (lightprobe.bake.engines has one module each).
BAKE_ENGINES = ("babylon", "gltf", "threejs", "filament", "playcanvas", "unity", "godot", "custom")
