"""``mjsound analyze``: the modal model of one mesh."""

from __future__ import annotations

import json
import sys
import time

__all__ = ["register"]


def register(sub) -> None:
    """Add ``analyze`` to an argparse ``subparsers``."""
    p = sub.add_parser(
        "analyze",
        help="modal analysis of a mesh: frequencies, decay rates, sound map",
        description=(
            "Compute the modal model of MESH made of MATERIAL. MESH is an OBJ/STL/PLY file in "
            "metres or a built-in shape: box:LX,LY,LZ  cylinder:RADIUS,LENGTH  sphere:RADIUS  "
            "capsule:RADIUS,LENGTH  bowl:RADIUS,THICKNESS. With no MESH, a 20 cm aluminium bowl."
        ),
    )
    p.add_argument("mesh", nargs="?", default="bowl:0.1,0.004", help="mesh file or built-in shape (default: bowl:0.1,0.004)")
    p.add_argument("--material", "-m", default="aluminium",
                   help="named material (steel, glass, oak, ...) or inline 'E=70e9,nu=0.33,rho=2700[,alpha=..,beta=..]'")
    p.add_argument("--method", choices=["auto", "hex", "tet", "facet", "shell"], default="auto",
                   help="discretization (default auto: shell triangles for thin curved walls, hex otherwise)")
    p.add_argument("--quality", choices=["draft", "default", "high"], default="default", help="elements per wavelength preset")
    p.add_argument("--resolution", type=int, default=None, help="N elements along the longest side (overrides --quality)")
    p.add_argument("--f-max", type=float, default=None, help="highest frequency in Hz (default min(20 kHz, 0.45*sample rate))")
    p.add_argument("--sample-rate", type=float, default=None, help="output sample rate in Hz (bounds f-max below Nyquist)")
    p.add_argument("--order", type=int, choices=[1, 2], default=2, help="element order: hex 2 = 20-node cells (default), 1 = 8-node; tet 2 = 10-node (default), 1 = 4-node")
    p.add_argument("--thickness", type=float, default=None, help="wall thickness in m (open meshes, shell method)")
    p.add_argument("--max-memory-gb", type=float, default=None,
                   help="cap on the analysis's estimated peak memory in GB (default $MJSOUND_MAX_MEMORY_GB or 8)")
    p.add_argument("--over-budget", choices=["coarsen", "refuse"], default="coarsen",
                   help="over the cap: lower the resolution (at most to draft, with a note) or refuse at once")
    p.add_argument("--no-cache", action="store_true", help="neither read nor write the model cache")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("-o", "--output", default=None, help="write the model to this .npz file")
    p.set_defaults(func=run)


def run(args) -> int:
    """Handler of ``mjsound analyze``."""
    from ..io import check_output_file
    from ..modal.analyze import analyze

    if args.output:
        check_output_file(args.output, (".npz",), "-o")
    if args.sample_rate is not None:
        from ..limits import check_sample_rate

        check_sample_rate(args.sample_rate, "--sample-rate")
    t0 = time.perf_counter()
    model = analyze(
        args.mesh, args.material, method=args.method, quality=args.quality, f_max=args.f_max,
        sample_rate=args.sample_rate, resolution=args.resolution, thickness=args.thickness,
        order=args.order, cache=not args.no_cache, progress=not args.json and sys.stderr.isatty(),
        max_memory_gb=args.max_memory_gb, over_budget=args.over_budget,
    )
    wall = time.perf_counter() - t0
    if args.output:
        model.save(args.output)
    if args.json:
        out = model.summary()
        out["wall_seconds"] = wall
        print(json.dumps(out))
        return 0
    f = model.frequencies_hz
    print(f"mesh       {args.mesh}")
    print(f"material   {model.material.name} (E={model.material.E:.3g} Pa, nu={model.material.nu}, rho={model.material.rho:g} kg/m^3)")
    print(f"method     {model.method}  {model.info.get('element', '')}  grid {model.info.get('grid', '-')}  dofs {model.dofs}")
    print(f"modes      {model.n_modes} between 20 Hz and {model.info['f_max']:.0f} Hz "
          f"(rigid removed: {model.info['n_rigid']}, overdamped dropped: {model.info['n_overdamped']})")
    print(f"mass       {model.mass_kg:.4g} kg")
    print(f"time       {model.seconds:.2f} s analysis ({model.info['solver']}, {model.info['slices']} slice(s)); {wall:.2f} s wall incl. cache")
    err = model.error_estimate_cents
    print(f"error est. {err:.1f} cents (vs 1.5x coarser solve)" if err == err else "error est. n/a")
    if len(f):
        print("first modes [Hz]: " + ", ".join(f"{x:.1f}" for x in f[:12]))
    if args.output:
        print(f"wrote      {args.output}")
    return 0
