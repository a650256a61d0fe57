"""``mjsound report accuracy`` and ``mjsound report stability``."""

from __future__ import annotations

__all__ = ["register"]


def _run_accuracy(args) -> int:
    from ..report.accuracy import run_report

    return run_report(output=args.output, quick=args.quick, plots=not args.no_plots, sections=args.sections,
                      json_path=args.json, from_json=args.from_json)


def _run_stability(args) -> int:
    from ..report.stability import run_report

    return run_report(quick=args.quick, output=args.output, hostile=not args.no_hostile)


def register(subparsers) -> None:
    """Add ``report accuracy`` and ``report stability`` to an argparse ``subparsers``."""
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
    a.add_argument("--sections", default="modal,fmax,synth,e2e,levels",
                   help="comma list of sections to run (levels alone: rewrite only that section of DIR/accuracy.md)")
    a.add_argument("--json", default=None, help="also dump every measured number to this JSON file")
    a.add_argument("--from-json", default=None, help="rewrite the Markdown and plots from a --json dump (no runs)")
    a.set_defaults(func=_run_accuracy)
    s = sub.add_parser(
        "stability",
        help="PASS/FAIL table of stiff, extreme and hostile cases with the measured quantity",
        description=(
            "Run the stability cases (tiny stiff objects, extreme materials, a large glass pane, "
            "sample rates, timesteps, impulses, 10 000 simultaneous contacts, an hour of ringing, "
            "degenerate meshes), then the hostile inputs and interruptions (each in a child process, with its "
            "peak memory), and print PASS/FAIL with what was measured. Exit status 1 if any fails."
        ),
    )
    s.add_argument("--quick", action="store_true", help="the quick form (a few minutes)")
    s.add_argument("--no-hostile", action="store_true",
                   help="skip the hostile-input and interruption cases (child processes, about a minute)")
    s.add_argument("-o", "--output", default=None,
                   help="also write the table as Markdown: a file, or a directory for DIR/stability.md")
    s.set_defaults(func=_run_stability)

    def _help(args, parser=p) -> int:
        parser.print_help()
        return 2

    p.set_defaults(func=_help)
