"""``lightprobe bake``: the whole image-based-lighting set for each engine, in the engine's own files."""

from __future__ import annotations

import argparse
from pathlib import Path

from .common import Number, add_option, add_probe, load, refuse

WORKING_BYTES_PER_PIXEL = 80  # the decomposition's ambient copy, directions and solid angles of every pixel


def register(sub) -> None:
    from ..util.names import BAKE_ENGINES

    p = sub.add_parser("bake", help="everything an engine needs for image-based lighting, in its own files",
                       description="For each engine a folder under -o with the files it loads — the GGX-"
                                   "prefiltered specular mips, the diffuse term, the skybox, with --lights the "
                                   "lights found as its directional lights — plus manifest.json (what each file "
                                   "holds) and USAGE.md (the code that loads it). Built aside and moved into place "
                                   "whole.")
    add_probe(p)
    p.add_argument("--for", dest="engines", required=True, metavar="ENGINE[,ENGINE…]|all",
                   help=f"engines: {', '.join(BAKE_ENGINES)}, or all")
    p.add_argument("--output", "-o", type=Path, required=True, help="the bake's folder (new or empty)")
    p.add_argument("--force", action="store_true", help="replace -o even if it is a non-empty folder (its files "
                                                        "are lost)")
    add_option(p, "--size", type=Number(int, 16, 1024), default=256,
               help="face size of the specular cube's level 0, a power of two")
    add_option(p, "--mips", type=Number(int, 1, 11), default=None,
               help="specular mip levels (default: the full chain down to 1 texel)")
    add_option(p, "--skybox-size", type=Number(int, 1, 4096), default=1024,
               help="skybox cube face size, or a panorama skybox's height; a power of two")
    add_option(p, "--intensity", type=Number(float, 1e-6, 1e6), default=1.0,
               help="factor applied to the probe's radiance in every file")
    p.add_argument("--lights", action="store_true",
                   help="also find the probe's area lights (Arbree, Walter & Bala 2005) and write them as the "
                        "engine's directional lights, the diffuse term then being the ambient remainder's")
    p.add_argument("--encoding", action="append", default=[], metavar="ENGINE=ENCODING",
                   help="an engine's encoding where it offers a choice (repeatable)")
    p.set_defaults(run=run)


def _encodings(items: list[str]) -> dict[str, str]:
    out = {}
    for item in items:
        engine, sep, encoding = item.partition("=")
        if not sep or not engine.strip() or not encoding.strip():
            refuse(f"--encoding takes ENGINE=ENCODING, got {item!r}")
        out[engine.strip().lower()] = encoding.strip().lower()
    return out


def run(args: argparse.Namespace) -> None:
    from ..bake import BakeOptions, bake, parse_engines
    from ..batch.task import file_digest
    from ..glossy.prefilter import prefilter_memory
    from .common import probe_path

    options = BakeOptions(parse_engines(args.engines), size=args.size, mips=args.mips,
                          skybox_size=args.skybox_size, intensity=args.intensity, lights=args.lights,
                          encodings=_encodings(args.encoding))
    from ..bake.run import check_bake_folder

    check_bake_folder(args.output, args.force)  # before the probe is read: a refused folder costs nothing
    path = probe_path(args.file)
    env = load(args.file, args.layout, working_bytes_per_pixel=WORKING_BYTES_PER_PIXEL,
               extra_bytes=2 * prefilter_memory(options.size), what="bake", kernels=True)
    digest, _ = file_digest(path)
    folders = bake(env, args.output, options, name=str(args.file or "(shipped probe)"), sha256=digest,
                   force=args.force)
    for engine, folder in folders.items():
        files = sorted(p.name for p in folder.iterdir())
        print(f"{engine}: {folder} ({', '.join(files)})")
