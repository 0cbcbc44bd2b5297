"""``lightprobe view``: bake a probe's lighting for the WebGL viewer and serve it on 127.0.0.1 (or export it)."""

from __future__ import annotations

import signal
import sys
from pathlib import Path

from .common import Number, add_option, add_probe, load, probe_path, refuse


def register(sub) -> None:
    p = sub.add_parser("view", help="the probe's lighting on a mesh, live in the browser (WebGL2)",
                       description="Bake what the viewer needs (SH for eq. 13, area lights + ambient SH, radiance "
                                   "maps of each BRDF at geodesic views, the split sum's prefiltered map and DFG "
                                   "table, the background, the mesh as GLB) into a cache folder, then serve the page "
                                   "on http://127.0.0.1 (a free port unless --port) until Ctrl-C; or, with --export, "
                                   "write a static folder any web server can host. The page: eq. 13 per pixel and "
                                   "per vertex, three.js's own LightProbe, area lights with soft shadows, RS-IBR "
                                   "synthesised on the GPU, per-pixel RS-IBR, split sum, SH basis functions; "
                                   "exposure, tone mapping, environment rotation, coefficient sliders, screenshots.")
    add_probe(p)
    p.add_argument("--mesh", type=Path, help="a mesh (OBJ, PLY, STL, glTF …), fitted to 1 unit on a ground plane; "
                                             "default: a sphere and a torus")
    p.add_argument("--brdf", action="append", metavar="SPEC",
                   help="a glossy material for the RS-IBR and split-sum methods (repeatable; default: gold GGX "
                        "α 0.2 and a red plastic α 0.15; 'none' for none)")
    add_option(p, "--views", type=Number(int, 12, 162), default=12, help="radiance-map views: 12, 42 or 162")
    add_option(p, "--map-size", type=Number(int, 16, 512), default=128, help="texels across each radiance map")
    add_option(p, "--port", type=Number(int, 0, 65535), default=0, help="port on 127.0.0.1 (0: a free one)")
    p.add_argument("--open", action="store_true", help="open the page in the default browser")
    p.add_argument("--export", type=Path, metavar="DIR",
                   help="write the page, its modules and the bake into DIR (new or empty) and exit")
    p.add_argument("--cache", type=Path, help="where bakes are kept (default ~/.cache/lightprobe/view)")
    p.set_defaults(run=run)


def run(args) -> None:
    from ..glossy.radiance import check_views
    from ..viewer.bake import DEFAULT_BRDFS, BakeOptions, bake, cache_folder, check_brdfs, check_inputs, read_manifest
    from ..viewer.server import ViewServer, export_static, three_root

    check_views(args.views)
    specs = DEFAULT_BRDFS if not args.brdf else tuple(b for b in args.brdf if b != "none")
    options = BakeOptions(brdfs=check_brdfs(specs), views=args.views, map_size=args.map_size)
    if args.export is not None and args.export.exists() and (not args.export.is_dir() or any(args.export.iterdir())):
        refuse(f"{args.export} exists and is not empty: give a new or empty folder for --export")
    three_root()  # the page's modules must be there before anything is baked
    source = probe_path(args.file)
    check_inputs(source, args.mesh)
    folder = cache_folder(source, args.mesh, options, args.cache, args.layout)
    if read_manifest(folder) is None:
        env = load(args.file, args.layout, working_bytes_per_pixel=64, kernels=True)
        print(f"baking into {folder} …", file=sys.stderr)
        bake(env, folder, args.mesh, options, source=source.name)
    if args.export is not None:
        export_static(folder, args.export)
        print(f"wrote {args.export} (serve it with any static web server; open index.html through it)")
        return
    # Ctrl-C is how serving ends: once the URL can be seen it must end in "stopped" (0) whenever it lands — a
    # KeyboardInterrupt raised between two statements (before the try, inside shutdown, in a print) would end the
    # command as "interrupted" (130). So from before the server starts, SIGINT only sets a flag the wait polls; the
    # handler takes no lock (it runs between any two bytecodes of this thread, which may hold that lock). Its first
    # call sets SIGINT to SIG_IGN, left so until exit: a second Ctrl-C has nothing left to stop, and SIG_IGN needs
    # no Python code to run, so it holds through the interpreter's exit too. A SIGINT the parent ignored (a
    # background job) stays ignored. Ctrl-C during the bake above stays "interrupted" (bake() leaves no partial
    # folder).
    stop: list[int] = []

    def ctrl_c(signum, frame) -> None:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        stop.append(signum)

    previous = signal.getsignal(signal.SIGINT)
    if previous is not signal.SIG_IGN:
        signal.signal(signal.SIGINT, ctrl_c)
    try:
        server = ViewServer(folder, args.port)
        try:
            print(f"lightprobe view: {server.url}  (Ctrl-C stops it)", flush=True)
            if args.open:
                import webbrowser

                webbrowser.open(server.url)
            server.wait(lambda: bool(stop))
        finally:
            server.close()
        print("lightprobe view: stopped", file=sys.stderr)
    finally:
        if not stop and previous not in (signal.SIG_IGN, None):  # None: a handler not set from Python
            signal.signal(signal.SIGINT, previous)
