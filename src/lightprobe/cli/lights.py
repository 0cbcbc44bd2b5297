"""``lightprobe lights``: a map as circular area lights plus an ambient remainder (Arbree, Walter & Bala 2005)."""

from __future__ import annotations

from pathlib import Path

from .common import Number, add_option, add_probe, load, refuse, write_text

MAX_AMBIENT_ORDER = 16
POINT_METHODS = {"mediancut": "median cut", "varmin": "variance minimisation"}
WORKING_BYTES_PER_PIXEL = 80  # the ambient copy, directions and solid angles of every pixel


def register(sub) -> None:
    p = sub.add_parser("lights", help="area lights + ambient map (Arbree, Walter & Bala 2005)",
                       description="Find the map's bright regions as circular area lights by the paper's "
                                   "centre-surround filter (docs/spec.md §5; every parameter below defaults to the "
                                   "paper's), and write them as JSON (format lightprobe.lights, version 1: "
                                   "world-frame directions, radii, RGB powers, the ambient's radiance SH).")
    from ..util.names import LIGHT_METHODS

    add_probe(p)
    p.add_argument("--output", "-o", type=Path, required=True, help="the lights JSON")
    p.add_argument("--method", choices=LIGHT_METHODS, default="arbree2005",
                   help="arbree2005: area lights + ambient (the paper); mediancut: Debevec's point lights "
                        "carrying the whole map (a baseline); varmin: Viriyothai & Debevec's variance "
                        "minimisation, the same but cut where each light best stands for its pixels")
    add_option(p, "--count", type=Number(int, 1, 4096), default=16,
               help="number of lights for --method mediancut or varmin (any number; a power of two is the papers' "
                    "own cut)")
    p.add_argument("--ambient", type=Path, help="also write the ambient map (the input's layout) to this image")
    p.add_argument("--preview", type=Path, help="also write a PNG of the probe with each light's cap outlined")
    add_option(p, "--ambient-order", type=Number(int, 0, MAX_AMBIENT_ORDER), default=12,
               help="SH order l_max of the ambient's coefficients (12: what the hybrid irradiance needs for 1 %% "
                    "accuracy; engines take the first 9)")
    add_option(p, "--inner-ratio", type=Number(float, 0.01, 0.99), default=0.75, help="r_i / r_o")
    add_option(p, "--surround-weight", type=Number(float, 0.0, 1000.0), default=10.0,
               help="weight of the annulus (negative) against the inner cap's +1")
    add_option(p, "--sizes", type=Number(int, 1, 200), default=20, help="number of filter sizes")
    add_option(p, "--min-extent", type=Number(float, 0.1, 180.0), default=4.5,
               help="smallest filter angular extent 2 r_o, degrees")
    add_option(p, "--max-extent", type=Number(float, 0.1, 180.0), default=45.0,
               help="largest filter angular extent 2 r_o, degrees")
    add_option(p, "--candidates", type=Number(float, 0.0001, 1.0), default=0.10,
               help="fraction of the brightest pixels tried as light centres")
    add_option(p, "--stop", type=Number(float, 0.0, 0.99), default=0.02,
               help="stop when a light has under this share of the power of those found before it")
    p.set_defaults(run=run)


def run(args) -> None:
    from ..util.files import atomic_outputs, check_output
    from ..maps.images import write_image
    from ..lights.decompose import LightParams, decompose, preview
    from ..lights.lightsfile import lights_json
    from ..sh.basis import project

    inputs = [args.file] if args.file else []
    params = LightParams(inner_ratio=args.inner_ratio, surround_weight=args.surround_weight, sizes=args.sizes,
                         min_extent_deg=args.min_extent, max_extent_deg=args.max_extent,
                         candidate_fraction=args.candidates, stop_fraction=args.stop)
    params.check()
    if args.method in POINT_METHODS:
        from ..lights.baselines import check_count

        check_count(args.count)
        if args.ambient is not None:
            refuse(f"--ambient: {POINT_METHODS[args.method]} has no ambient map (its point lights carry the whole map)")
    # one file named twice is refused; every output is written aside and all are renamed together at the end, so a
    # failure leaves every old file
    with atomic_outputs([args.output, args.ambient, args.preview]):
        for path in (args.output, args.ambient, args.preview):
            if path is not None:
                check_output(path, inputs, text=path == args.output)
        env = load(args.file, args.layout, working_bytes_per_pixel=WORKING_BYTES_PER_PIXEL, kernels=True)
        if args.method in POINT_METHODS:
            done = _point_lights(args, env, inputs)
        else:
            dec = decompose(env, params)
            text = lights_json(dec, project(dec.ambient, args.ambient_order), str(args.file or "(shipped probe)"))
            if args.ambient is not None:
                dec.ambient.save(args.ambient, inputs=inputs)
            if args.preview is not None:
                write_image(args.preview, preview(env, dec.lights), encoded=True, inputs=inputs)
            write_text(args.output, text, inputs)
            done = (f"wrote {args.output} ({len(dec.lights)} lights, {100 * (1 - _ambient_share(text)):.0f} % of the "
                    "power)")
    print(done)


def _point_lights(args, env, inputs) -> str:
    import json
    import time

    from ..lights.baselines import median_cut, variance_minimisation
    from ..maps.images import write_image
    from ..lights.decompose import preview
    from ..lights.lightsfile import point_lights_document

    name = POINT_METHODS[args.method]
    t0 = time.perf_counter()
    lights = (median_cut if args.method == "mediancut" else variance_minimisation)(env, args.count)
    doc = point_lights_document(lights, env.integral(), args.method, {"count": args.count, "working_rows": 256},
                                {name: time.perf_counter() - t0}, str(args.file or "(shipped probe)"))
    if args.preview is not None:
        write_image(args.preview, preview(env, lights), encoded=True, inputs=inputs)
    write_text(args.output, json.dumps(doc, indent=1, allow_nan=False) + "\n", inputs)
    return f"wrote {args.output} ({len(lights)} point lights by {name})"


def _ambient_share(text: str) -> float:
    import json

    return json.loads(text)["shares"]["ambient"]
