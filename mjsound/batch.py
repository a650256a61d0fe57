"""Batch sonification of rollout datasets: a local process pool, or a Ray cluster.

``sonify_batch(rollouts, scene_xml, outdir)`` (CLI: ``mjsound sonify-batch``) turns every
rollout ``.npz`` into ``OUTDIR/<stem>.wav`` (and optionally ``OUTDIR/<stem>.rrd``), each
exactly the file ``mjsound sonify SCENE --rollout R -o <stem>.wav`` writes with the same
parameters: every task *is* a :func:`mjsound.sim.rollout.sonify` call, so the audio does not
depend on the worker count, the backend or the order.

Work sharing
------------
The scene's modal models are computed once, in the driver (``SoundScene.from_model``, without
the mode budget, which every task applies itself exactly as ``sonify`` does), and shared with
the workers: through the pool initializer (once per worker process) on the local path, through
Ray's object store (one ``ray.put``) on the Ray path. Workers never run a modal analysis for a
geom the driver analysed.

Resuming
--------
Next to each WAV a sidecar ``<stem>.json`` is written *after* it (both atomically: temporary
file + ``os.replace``), holding the SHA-256 of the rollout file, of the scene (the MJCF text
and the compiled model), the parameters, and the WAV's SHA-256 and frame count. A rerun skips a
rollout whose sidecar matches and whose WAV opens with that frame count and hash; anything else
(missing, truncated or corrupt output, changed rollout/scene/parameters) is redone. An
interrupted run therefore never leaves a half-written file that a rerun would trust.

Failures
--------
A rollout that raises (unreadable file, wrong shapes, ...) is reported with its error and the
others go on. A worker *process* that dies (crash, OOM kill) is retried: Ray retries the task
(``max_retries``); the local pool is rebuilt, the tasks that were running on it are retried
one at a time (so a rollout that kills its worker every time fails alone, after
``max_retries`` retries, instead of taking innocent neighbours with it).

Ray
---
``address="auto"`` joins a running cluster (``ray start --head`` / a cluster launcher),
``address="ray://host:10001"`` or ``"host:6379"`` a remote one, ``address="local"`` starts a
private single-machine instance (``workers`` CPUs). If Ray is already initialised in this
process it is used as is. Every node needs mjsound installed and must see the rollouts, the
scene and OUTDIR at the same paths (a shared file system). ``ray`` is imported only here
(``pip install 'mjsound[batch]'``).
"""

from __future__ import annotations

import contextlib
import os
import sys
import time as _time
import traceback

from .batch_files import (SIDECAR_FORMAT, _canonical, _json_default, _outputs, _scene_hash,  # noqa: F401
                          _sha256_file, _write_json_atomic, find_rollouts, output_is_complete)

__all__ = ["sonify_batch", "find_rollouts", "output_is_complete", "SIDECAR_FORMAT"]

#: Test hook: a path; the first task to create it (O_EXCL) kills its worker with os._exit(3).
_CRASH_ENV = "MJSOUND_BATCH_TEST_CRASH_ONCE"


# ---------------------------------------------------------------------- worker side
_WORKER_MODELS = None  # set by the local pool's initializer


def _die_with_parent(parent_pid: int) -> None:
    """End this worker when the driver process ends, however it ends (a SIGKILL or the OOM
    killer included): on Linux the kernel sends SIGKILL when the parent dies
    (``prctl(PR_SET_PDEATHSIG)``); everywhere a daemon thread also polls the parent's pid
    once a second and exits when the worker has been re-parented."""
    import threading

    if sys.platform.startswith("linux"):
        try:
            import ctypes
            import signal

            libc = ctypes.CDLL(None, use_errno=True)
            PR_SET_PDEATHSIG = 1
            libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):  # pragma: no cover - no libc prctl: the thread below
            pass
    if os.getppid() != parent_pid:  # the driver died before the call above
        os._exit(1)

    def watch():
        while True:
            _time.sleep(1.0)
            if os.getppid() != parent_pid:
                os._exit(1)

    threading.Thread(target=watch, name="mjsound-parent-watch", daemon=True).start()


def _init_local_worker(models, parent_pid=None) -> None:
    global _WORKER_MODELS
    if parent_pid is not None:
        _die_with_parent(parent_pid)
    _WORKER_MODELS = models


def _run_local(job) -> dict:
    return _run_job(job, _WORKER_MODELS)


def _maybe_crash(marker) -> None:
    if not marker:
        return
    try:
        fd = os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
    except FileExistsError:
        return
    os.close(fd)
    os._exit(3)


def _run_job(job, models) -> dict:
    """One rollout: ``sonify`` (+ rerun recording) then the sidecar. Never raises."""
    _maybe_crash(job.get("crash_marker"))
    t0 = _time.perf_counter()
    res = {"rollout": job["rollout"], "stem": job["stem"], "wav": job["wav"], "ok": False, "pid": os.getpid()}
    rrd_tmp = None
    try:
        from .io import commit_temp, temp_beside
        from .sim.rollout import sonify

        kwargs = dict(job["sonify"])
        kwargs.update(rollout=job["rollout"], out=job["wav"], progress=False, keep_audio=False)
        if os.path.exists(job["sidecar"]):  # about to replace the WAV: the old sidecar is void
            os.unlink(job["sidecar"])
        kwargs["models"] = models  # computed once by the driver
        if job.get("rrd"):
            from .rerun_log import log_sonify

            fd, rrd_tmp = temp_beside(job["rrd"], suffix=".rrd")
            os.close(fd)
            s = log_sonify(rrd_tmp, job["scene_xml"], **kwargs)
        else:
            s = sonify(job["scene_xml"], **kwargs)
        if rrd_tmp is not None:
            rrd_sha = _sha256_file(rrd_tmp)
            commit_temp(rrd_tmp, job["rrd"])
            rrd_tmp = None
        else:
            rrd_sha = None
        import soundfile as sf

        info = sf.info(job["wav"])
        summary = {k: s.get(k) for k in ("mode", "events", "impacts", "sim_seconds", "wall_seconds", "peak_pa",
                                         "clipped", "max_qpos_error", "samples", "channels")}
        meta = {
            "format": SIDECAR_FORMAT,
            "rollout": os.path.abspath(job["rollout"]),
            "rollout_sha256": job["rollout_sha256"],
            "scene": os.path.abspath(job["scene_xml"]),
            "scene_sha256": job["scene_sha256"],
            "params": job["params"],
            "wav": os.path.basename(job["wav"]),
            "wav_sha256": _sha256_file(job["wav"]),
            "frames": int(info.frames),
            "sample_rate": int(info.samplerate),
            "channels": int(info.channels),
            "rrd": os.path.basename(job["rrd"]) if job.get("rrd") else None,
            "rrd_sha256": rrd_sha,
            "summary": summary,
        }
        _write_json_atomic(job["sidecar"], meta)
        res.update(ok=True, audio_seconds=float(s["sim_seconds"]), summary=_canonical(summary),
                   analysis_seconds=float(s.get("analysis_seconds") or 0.0))
    except Exception as exc:  # reported, never raised: one bad rollout does not stop the batch
        res.update(error=f"{type(exc).__name__}: {exc}", traceback=traceback.format_exc(limit=6))
        if rrd_tmp is not None and os.path.exists(rrd_tmp):
            os.unlink(rrd_tmp)
    res["task_seconds"] = _time.perf_counter() - t0
    return res


# ---------------------------------------------------------------------- backends
def _run_pool(jobs, models, workers, max_retries, on_result) -> dict:
    """Local ``ProcessPoolExecutor`` (spawn). Returns timing info."""
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    ctx = multiprocessing.get_context("spawn")
    queue = list(range(len(jobs)))  # fresh jobs, in order
    solo = []  # jobs whose worker died: rerun one at a time, so a death names its job
    attempts = {}
    restarts = 0
    while queue or solo:
        with ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_init_local_worker,
                                 initargs=(models, os.getpid())) as ex:
            inflight = {}  # at most `workers`: a dead worker implicates only these
            dead = []
            while (queue or solo or inflight) and not dead:
                if solo:
                    if not inflight:
                        i = solo.pop(0)
                        inflight[ex.submit(_run_local, jobs[i])] = i
                else:
                    while queue and len(inflight) < workers:
                        i = queue.pop(0)
                        inflight[ex.submit(_run_local, jobs[i])] = i
                done, _ = wait(list(inflight), return_when=FIRST_COMPLETED)
                for fut in done:
                    i = inflight.pop(fut)
                    try:
                        res = fut.result()
                    except BrokenProcessPool:
                        dead.append(i)
                        continue
                    on_result(i, res)
            dead.extend(inflight.values())  # the pool is gone: so are the tasks still in flight
        if dead:
            restarts += 1
            for i in dead:
                attempts[i] = attempts.get(i, 0) + 1
                if attempts[i] > max_retries:
                    on_result(i, {"rollout": jobs[i]["rollout"], "stem": jobs[i]["stem"], "wav": jobs[i]["wav"],
                                  "ok": False, "error": f"worker process died ({attempts[i]} times)"})
                else:
                    solo.append(i)
    return {"pool_restarts": restarts}


def _import_ray():
    try:
        import ray
    except ImportError as exc:
        raise ImportError(
            "the Ray backend needs ray: pip install 'mjsound[batch]' (or pip install 'ray>=2.9'); "
            "without --address the batch runs on a local process pool"
        ) from exc
    return ray


@contextlib.contextmanager
def _ray_session(address, workers, ray_init_kwargs):
    """Join (``address``) or start (``"local"``) Ray unless already initialised; yields init info."""
    import logging

    ray = _import_ray()
    started = False
    t0 = _time.perf_counter()
    if not ray.is_initialized():
        kw = {"include_dashboard": False, "logging_level": logging.WARNING, "log_to_driver": False}
        if address in (None, "local"):
            if workers:
                kw["num_cpus"] = int(workers)
        else:
            kw["address"] = address
        kw.update(ray_init_kwargs or {})
        try:
            ray.init(**kw)
        except ConnectionError as exc:
            raise ConnectionError(f"no Ray cluster at address {address!r} ({exc}); start one with `ray start --head`, "
                                  "use --address local for a private instance, or leave --address out for the "
                                  "local process pool") from exc
        started = True
    try:
        yield {"ray_init_seconds": _time.perf_counter() - t0, "ray_cpus": int(ray.cluster_resources().get("CPU", 1))}
    finally:
        if started:
            ray.shutdown()


def _run_ray(jobs, models, workers, max_retries, on_result, cpus) -> dict:
    import ray

    window = int(workers) if workers else 2 * max(1, cpus)
    task = ray.remote(num_cpus=1, max_retries=int(max_retries), retry_exceptions=False)(_run_job)
    models_ref = ray.put(models)  # once; every task reads it from the object store
    queue = list(range(len(jobs)))
    inflight = {}
    while queue or inflight:
        while queue and len(inflight) < window:
            i = queue.pop(0)
            inflight[task.remote(jobs[i], models_ref)] = i
        done, _ = ray.wait(list(inflight), num_returns=1)
        for ref in done:
            i = inflight.pop(ref)
            try:
                res = ray.get(ref)
            except Exception as exc:  # the worker died more than max_retries times, or Ray failed
                msg = str(exc).strip().splitlines()
                res = {"rollout": jobs[i]["rollout"], "stem": jobs[i]["stem"], "wav": jobs[i]["wav"],
                       "ok": False, "error": f"{type(exc).__name__}: {msg[0] if msg else ''}"}
            on_result(i, res)
    return {"tasks_in_flight": window}


# ---------------------------------------------------------------------- API
def _unique_rollouts(rollouts, outdir) -> list:
    """The rollout files of ``rollouts`` (:func:`find_rollouts`), absolute and each once;
    ValueError when two would write the same ``<stem>.wav`` in ``outdir``."""
    paths = [os.path.abspath(p) for p in find_rollouts(rollouts)]
    seen = {}
    for p in paths:
        stem = _outputs(outdir, p)[0]
        if stem in seen and seen[stem] != p:
            raise ValueError(f"two rollouts would write {stem}.wav: {seen[stem]} and {p} (rename one)")
        seen[stem] = p
    return list(dict.fromkeys(paths))


def _pending_jobs(paths, outdir, scene_xml, scene_sha, params, sonify_kwargs, resume, rrd, crash_marker):
    """What is left to do: ``(jobs, skipped stems, failed)``. A rollout whose outputs are
    complete and valid for these inputs (:func:`output_is_complete`) is skipped when
    ``resume``; one that cannot be read is failed with its error; the rest become jobs."""
    jobs, skipped, failed = [], [], []
    for p in paths:
        stem, wav, side, rrd_path = _outputs(outdir, p)
        try:
            rsha = _sha256_file(p)
        except OSError as exc:
            failed.append({"rollout": p, "stem": stem, "error": f"{type(exc).__name__}: {exc}"})
            continue
        if resume and output_is_complete(wav, side, rsha, scene_sha, params, rrd_path if rrd else None):
            skipped.append(stem)
            continue
        jobs.append({
            "rollout": p, "stem": stem, "wav": wav, "sidecar": side, "rrd": rrd_path if rrd else None,
            "scene_xml": scene_xml, "rollout_sha256": rsha, "scene_sha256": scene_sha, "params": params,
            "sonify": sonify_kwargs, "crash_marker": crash_marker,
        })
    return jobs, skipped, failed


def sonify_batch(
    rollouts,
    scene_xml,
    outdir,
    workers: int | None = None,
    address: str | None = None,
    *,
    duration: float | None = None,
    timestep: float | None = None,
    sample_rate: int = 48000,
    materials=None,
    mode: str = "auto",
    quality: str = "default",
    budget_modes: int | None = None,
    full_scale_pa: float | None = None,
    normalize: bool = False,
    rrd: bool = False,
    resume: bool = True,
    max_retries: int = 2,
    progress: bool = True,
    ray_init_kwargs: dict | None = None,
) -> dict:
    """Sonify many rollouts of one scene: ``OUTDIR/<stem>.wav`` (+ ``.json`` sidecar, ``.rrd``).

    Parameters
    ----------
    rollouts : iterable of path | path
        Rollout ``.npz`` files or directories of them (see :func:`find_rollouts`). Stems must be
        unique (they name the outputs).
    scene_xml : path
        MJCF scene, the same for every rollout.
    outdir : path
        Output directory (created).
    workers : int, optional
        Local pool size (default ``os.cpu_count()``); on Ray the number of tasks in flight
        (default twice the cluster's CPUs) and, with ``address="local"``, the CPUs of the instance.
    address : str, optional
        None: local process pool. ``"auto"``, a Ray address, or ``"local"`` (a private Ray
        instance): run on Ray.
    duration, timestep, sample_rate, materials, mode, quality, budget_modes, full_scale_pa, normalize
        As :func:`mjsound.sim.rollout.sonify` (``mode`` ``auto``/``resim``/``replay``).
    rrd : bool
        Also write a rerun recording ``<stem>.rrd`` (needs ``rerun-sdk``).
    resume : bool
        Skip rollouts whose outputs are complete and valid (default); False redoes all.
    max_retries : int
        Retries of a task whose worker process died.
    progress : bool
        tqdm progress bars (modal analysis, rollouts).
    ray_init_kwargs : dict, optional
        Extra ``ray.init`` arguments when this call starts/joins Ray.

    Returns
    -------
    dict
        ``n_rollouts``, ``done`` / ``skipped`` (stems), ``failed`` (list of ``{"rollout",
        "error"}``), ``results`` (per sonified rollout: ``stem``, ``wav``, ``audio_seconds``,
        ``task_seconds``, ...), ``audio_seconds`` (audio written this run), ``wall_seconds``,
        ``analysis_seconds`` (driver's modal analysis), ``throughput`` (audio seconds per wall
        second, everything included), ``backend``, ``workers``, ``outdir``.
    """
    import mujoco

    from . import __version__
    from .limits import check_duration, check_sample_rate, check_timestep
    from .sim.rollout import load_materials

    t_start = _time.perf_counter()
    if mode not in ("auto", "resim", "replay"):
        raise ValueError(f"mode={mode!r}: choose 'auto', 'resim' or 'replay'")
    if workers is not None and int(workers) < 1:
        raise ValueError(f"workers={workers} must be >= 1")
    scene_xml = os.path.abspath(os.fspath(scene_xml))
    outdir = os.path.abspath(os.fspath(outdir))
    if os.path.exists(outdir) and not os.path.isdir(outdir):
        raise ValueError(f"output directory {outdir!r} is a file: give a directory (created if missing) for "
                         "<stem>.wav and <stem>.json")
    sample_rate = check_sample_rate(sample_rate)
    if timestep is not None:
        timestep = check_timestep(timestep)
    if duration is not None:
        duration = check_duration(duration)
    paths = _unique_rollouts(rollouts, outdir)
    os.makedirs(outdir, exist_ok=True)

    model = mujoco.MjModel.from_xml_path(scene_xml)
    if timestep is not None:
        model.opt.timestep = float(timestep)
    mats = load_materials(materials)
    scene_sha = _scene_hash(scene_xml, model)
    sonify_kwargs = dict(duration=duration, timestep=timestep, sample_rate=int(sample_rate), materials=mats,
                         mode=mode, quality=quality, budget_modes=budget_modes, full_scale_pa=full_scale_pa,
                         normalize=bool(normalize))
    params = _canonical(dict(sonify_kwargs, mjsound=__version__, mujoco=mujoco.__version__))
    crash_marker = os.environ.get(_CRASH_ENV) or None

    jobs, skipped, failed = _pending_jobs(paths, outdir, scene_xml, scene_sha, params, sonify_kwargs, resume, rrd,
                                          crash_marker)

    backend = "local" if address is None else "ray"
    n_workers = int(workers) if workers else (os.cpu_count() or 1)
    info = {}
    session = _ray_session(address, workers, ray_init_kwargs) if (backend == "ray" and jobs) else contextlib.nullcontext({})
    results = []
    bar = None
    t_run = _time.perf_counter()
    with session as ray_info:  # join Ray before the analysis: a bad address fails fast
        info.update(ray_info)
        # -------------------------------------------------------- modal models, once
        models, analysis_s = {}, 0.0
        if jobs:
            from .sim.scene import SoundScene

            t0 = _time.perf_counter()
            scene = SoundScene.from_model(model, materials=mats, sample_rate=int(sample_rate), quality=quality,
                                          budget_modes=None, progress=progress)
            models = {s.name: s.model for s in scene.sounding}
            analysis_s = _time.perf_counter() - t0

        # -------------------------------------------------------- run
        if progress and jobs:
            try:
                from tqdm.auto import tqdm

                bar = tqdm(total=len(jobs), desc="mjsound: sonify-batch", unit="rollout")
            except ImportError:  # pragma: no cover
                bar = None
        t_run = _time.perf_counter()
        audio_total = [0.0]

        def on_result(i, res):
            results.append(res)
            if res.get("ok"):
                audio_total[0] += res.get("audio_seconds", 0.0)
            else:
                failed.append({"rollout": res["rollout"], "stem": res["stem"], "error": res.get("error", "?"),
                               **({"traceback": res["traceback"]} if res.get("traceback") else {})})
            if bar is not None:
                el = _time.perf_counter() - t_run
                bar.set_postfix_str(f"{audio_total[0] / el:.2f} audio-s/s" + (f", {len(failed)} failed" if failed else ""))
                bar.update(1)

        try:
            if jobs and backend == "local":
                info.update(_run_pool(jobs, models, min(n_workers, len(jobs)), int(max_retries), on_result))
            elif jobs:
                info.update(_run_ray(jobs, models, workers, int(max_retries), on_result, info.get("ray_cpus", 1)))
        finally:
            if bar is not None:
                bar.close()
    wall = _time.perf_counter() - t_start
    done = sorted(r["stem"] for r in results if r.get("ok"))
    audio_s = float(sum(r.get("audio_seconds", 0.0) for r in results if r.get("ok")))
    run_wall = _time.perf_counter() - t_run
    return {
        "n_rollouts": len(paths),
        "done": done,
        "skipped": sorted(skipped),
        "failed": failed,
        "results": sorted((r for r in results if r.get("ok")), key=lambda r: r["stem"]),
        "audio_seconds": audio_s,
        "wall_seconds": wall,
        "run_seconds": run_wall if jobs else 0.0,
        "analysis_seconds": analysis_s,
        "throughput": audio_s / wall if wall > 0 else 0.0,
        "task_seconds": float(sum(r.get("task_seconds", 0.0) for r in results)),
        "backend": backend,
        "workers": n_workers if backend == "local" else info.get("tasks_in_flight", workers),
        "outdir": outdir,
        **info,
    }
