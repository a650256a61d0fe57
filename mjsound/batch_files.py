"""A batch's files (:mod:`mjsound.batch`): which rollouts, what each writes
(``<stem>.wav``, ``<stem>.json``, ``<stem>.rrd``), the hashes of rollout and scene, and whether
a rollout's outputs are complete and valid for the same inputs (``Resuming`` there)."""

from __future__ import annotations

import hashlib
import json
import os

__all__ = ["find_rollouts", "output_is_complete", "SIDECAR_FORMAT"]

#: ``format`` field of the sidecar JSON; a sidecar of another format is never trusted.
SIDECAR_FORMAT = "mjsound-batch/1"

_CHUNK = 1 << 20


def _sha256_file(path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while True:
            b = fh.read(_CHUNK)
            if not b:
                break
            h.update(b)
    return h.hexdigest()


def _scene_hash(scene_xml, model) -> str:
    """SHA-256 of the MJCF text and of the compiled model (catches included files and meshes)."""
    import mujoco
    import numpy as np

    h = hashlib.sha256()
    with open(scene_xml, "rb") as fh:
        h.update(fh.read())
    buf = np.zeros(mujoco.mj_sizeModel(model), np.uint8)
    mujoco.mj_saveModel(model, None, buf)
    h.update(buf.tobytes())
    return h.hexdigest()


def _write_json_atomic(path, obj) -> None:
    from .io import atomic_open

    with atomic_open(path) as fh:
        json.dump(obj, fh, indent=1, sort_keys=True, default=_json_default)
        fh.write("\n")


def _json_default(o):
    try:
        import numpy as np

        if isinstance(o, np.generic):
            return o.item()
        if isinstance(o, np.ndarray):
            return o.tolist()
    except ImportError:  # pragma: no cover
        pass
    return str(o)


def find_rollouts(paths) -> list:
    """Rollout files from files and directories (a directory gives its ``*.npz``, sorted).

    Missing paths are kept (they are reported as failed rollouts, not raised).
    """
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    out = []
    for p in paths:
        p = os.fspath(p)
        if os.path.isdir(p):
            out.extend(sorted(os.path.join(p, f) for f in os.listdir(p) if f.endswith(".npz")))
        else:
            out.append(p)
    return out


def _outputs(outdir, rollout) -> tuple:
    stem = os.path.splitext(os.path.basename(rollout))[0]
    base = os.path.join(os.fspath(outdir), stem)
    return stem, base + ".wav", base + ".json", base + ".rrd"


def output_is_complete(wav, sidecar, rollout_sha256, scene_sha256, params, rrd=None) -> bool:
    """Whether ``wav`` + ``sidecar`` are a finished output of this rollout, scene and parameters.

    Checks the sidecar (format, hashes, parameters), that the WAV's SHA-256 matches and that it
    opens with the recorded sample rate, channels and frame count; with ``rrd`` also that the
    recording exists with its recorded hash.
    """
    try:
        with open(sidecar) as fh:
            meta = json.load(fh)
        if (meta.get("format") != SIDECAR_FORMAT or meta.get("rollout_sha256") != rollout_sha256
                or meta.get("scene_sha256") != scene_sha256 or meta.get("params") != _canonical(params)):
            return False
        if _sha256_file(wav) != meta.get("wav_sha256"):
            return False
        import soundfile as sf

        info = sf.info(wav)
        if (info.frames != meta.get("frames") or info.samplerate != meta.get("sample_rate")
                or info.channels != meta.get("channels")):
            return False
        if rrd is not None and (not meta.get("rrd_sha256") or _sha256_file(rrd) != meta["rrd_sha256"]):
            return False
        return True
    except Exception:
        return False


def _canonical(obj):
    """JSON round trip: what a sidecar holds, to compare parameters with it."""
    return json.loads(json.dumps(obj, sort_keys=True, default=_json_default))
