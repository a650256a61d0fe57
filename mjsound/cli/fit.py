"""``mjsound fit``: a modal model (and optionally a material) from an impact recording."""

from __future__ import annotations

import argparse
import json
import sys
import warnings

__all__ = ["register"]


def register(subparsers) -> argparse.ArgumentParser:
    """Add the ``fit`` subcommand to an argparse ``subparsers`` object."""
    p = subparsers.add_parser(
        "fit",
        help="fit a modal model (frequencies, decays, amplitudes) to an impact recording",
        description=(
            "Estimate the modes of an impact recording with band-split ESPRIT and least squares, "
            "report the residual the model leaves, and optionally write a one-point ModalModel "
            "(.npz) that plays in the synthesizer. Multi-channel files are mixed to mono unless "
            "--channel is given. With --mesh, also fit a material (stiffness scale, Rayleigh "
            "alpha/beta) so that the analysed mesh matches the recording."
        ),
    )
    p.add_argument("recording", help="impact recording (WAV/FLAC/OGG)")
    p.add_argument("--modes", type=int, default=None, help="keep at most N modes (the most energetic)")
    p.add_argument("-o", "--output", default=None, help="write the fitted ModalModel to this .npz")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--channel", type=int, default=None, help="fit this channel only (default: mix all)")
    p.add_argument("--f-min", type=float, default=20.0, help="lowest frequency [Hz] (default 20)")
    p.add_argument("--f-max", type=float, default=None, help="highest frequency [Hz] (default 0.45 * sample rate)")
    p.add_argument("--min-snr-db", type=float, default=15.0, help="significance of a mode [dB] (default 15)")
    p.add_argument("--mass-kg", type=float, default=None, help="object mass stored in the model (Hertz contact)")
    p.add_argument("--mesh", default=None, help="also fit a material for this mesh / built-in shape")
    p.add_argument("--material", default="aluminium", help="reference material for --mesh (default aluminium)")
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    """Handler of ``mjsound fit``."""
    from ..fit import FitWarning, fit_material, fit_recording

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FitWarning)  # reported below / in the JSON
        fit = fit_recording(args.recording, n_modes=args.modes, channel=args.channel, f_min=args.f_min,
                            f_max=args.f_max, min_snr_db=args.min_snr_db)
    mfit = None
    if args.mesh:
        mfit = fit_material(args.mesh, fit, args.material)
    if args.output:
        fit.to_model(material=mfit.material if mfit else None, mass_kg=args.mass_kg).save(args.output)
    if args.json:
        out = fit.summary()
        if mfit is not None:
            out["material_fit"] = mfit.summary()
        if args.output:
            out["output"] = args.output
        print(json.dumps(out))
        return 0

    for w in fit.warnings:
        print(f"warning: {w}", file=sys.stderr)
    print(f"recording  {args.recording} ({fit.channels}, {fit.sample_rate} Hz)")
    print(f"onset      {fit.onset_s:.5f} s; analysed {fit.analysis_start_s:.3f}..{fit.analysis_end_s:.3f} s; "
          f"peak {fit.snr_db:.1f} dB over the noise floor")
    print(f"modes      {fit.n_modes} (the recording supports {fit.modes_supported}); residual {fit.residual_db:.1f} dB; {fit.seconds:.2f} s")
    print("   f [Hz]    d [1/s]   T60 [s]   amplitude")
    for f, d, a in zip(fit.frequencies_hz, fit.decay_per_s, fit.amplitudes):
        print(f"{f:9.2f}  {d:9.3f}  {6.91 / d:8.3f}  {a:10.4g}")
    if mfit is not None:
        m = mfit.material
        print(f"material   E={m.E:.4g} Pa (x{mfit.stiffness_scale:.4f}), alpha={m.alpha:.4g} 1/s, beta={m.beta:.4g} s; "
              f"{len(mfit.matches)} modes matched, rms {mfit.rms_cents:.1f} cents")
    if args.output:
        print(f"wrote      {args.output}")
    return 0
