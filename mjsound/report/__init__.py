"""Reproducible reports: accuracy against run time, and stability on stiff and extreme cases.

``mjsound report accuracy [--quick] [-o DIR]`` writes ``DIR/accuracy.md`` and PNG plots
(:mod:`mjsound.report.accuracy`; matplotlib is needed for the plots only).
``mjsound report stability [--quick] [-o FILE_OR_DIR]`` prints a PASS/FAIL table with the measured
quantity of every case (:mod:`mjsound.report.stability`).

Nothing heavy is imported here: the CLI imports this module to register the subcommands.
"""

from __future__ import annotations

__all__ = ["register_cli"]


def _run_accuracy(args) -> int:
    from .accuracy import main

    argv = (["--quick"] if args.quick else []) + ["-o", args.output]
    if args.no_plots:
        argv.append("--no-plots")
    return main(argv)


def _run_stability(args) -> int:
    from .stability import main

    argv = ["--quick"] if args.quick else []
    if args.output:
        argv += ["-o", args.output]
    return main(argv)


def register_cli(subparsers) -> None:
    """Add ``mjsound report accuracy`` and ``mjsound report stability``."""
    p = subparsers.add_parser(
        "report",
        help="measured reports: accuracy against run time, stability on extreme cases",
        description="Measured, reproducible reports (see reports/ in the repository).",
    )
    sub = p.add_subparsers(dest="report", metavar="REPORT")
    a = sub.add_parser(
        "accuracy",
        help="modal frequency error, synthesis error and end-to-end spectra against wall time",
        description=(
            "Run every measurement and write DIR/accuracy.md with PNG plots. Each point is a "
            "measured run (modal points in a child process each, for their peak memory). "
            "The full report takes about 10-15 minutes on 2 cores; --quick under a minute."
        ),
    )
    a.add_argument("--quick", action="store_true", help="a small subset that finishes in under a minute")
    a.add_argument("-o", "--output", default="reports", help="output directory (default: reports)")
    a.add_argument("--no-plots", action="store_true", help="skip the PNG plots (no matplotlib needed)")
    a.set_defaults(func=_run_accuracy)
    s = sub.add_parser(
        "stability",
        help="PASS/FAIL table of stiff and extreme cases with the measured quantity",
        description=(
            "Run the stability cases (tiny stiff objects, extreme materials, a large glass pane, "
            "sample rates, timesteps, impulses, 10 000 simultaneous contacts, an hour of ringing, "
            "degenerate meshes) and print PASS/FAIL with what was measured. Exit status 1 if any fails."
        ),
    )
    s.add_argument("--quick", action="store_true", help="the quick form (under 90 s; used by the test suite)")
    s.add_argument("-o", "--output", default=None,
                   help="also write the table as Markdown: a file, or a directory for DIR/stability.md")
    s.set_defaults(func=_run_stability)

    def _help(args, parser=p) -> int:
        parser.print_help()
        return 2

    p.set_defaults(func=_help)
