"""`RerunLogger`: a rerun recording (``.rrd`` file) of a sonified MuJoCo simulation.

Everything is logged on the ``sim_time`` timeline (simulation seconds, never wall time):

==============================  ====================================================================
entity                          content
==============================  ====================================================================
``/world/<body>``               ``Transform3D`` (body pose, every ``pose_rate_hz``; static bodies once)
``/world/<body>/<geom>``        ``Mesh3D`` (the geom's surface in its body frame; static)
``/world/contacts/points``      ``Points3D`` of the active contacts (with ``pose_rate_hz``)
``/world/contacts/forces``      ``Arrows3D``: force on geom 2 of each contact (``force_scale`` m/N)
``/events``                     ``TextLog``: one line per impact (geoms, impulse), at its time
``/audio/<mic>/waveform``       ``Scalars`` pressure [Pa], every sample (``send_columns``)
``/audio/<mic>/spectrogram``    ``Tensor`` (freq x time) of 20 log10 |STFT| [dB re 20 uPa], static
``/audio/contact/<site>/...``   the same for a contact microphone: acceleration [m/s^2]
``/audio/take``                 ``AssetAudio`` (WAV, all mics as channels), logged at the first
                                sample's time, shown and played by an ``AudioView``
==============================  ====================================================================

The blueprint has a 3D view of ``/world``, the audio view, a time-series view of the
waveforms, a tensor view of each spectrogram and the event log. Only a file is written (no
viewer is spawned); ``rerun`` is imported when a logger is created, never by ``import mjsound``.

Use
---
>>> log = RerunLogger("take.rrd", model, sim=sim)          # doctest: +SKIP
>>> for _ in range(n):                                       # doctest: +SKIP
...     mujoco.mj_step(model, data)
...     log.log_step(data, sim.step())
>>> log.close()                                              # doctest: +SKIP

or :func:`log_sonify` for :func:`mjsound.sim.rollout.sonify` with a recording.
"""

from __future__ import annotations

import io
import os

import numpy as np

__all__ = ["RerunLogger", "log_sonify", "geom_surface"]


def _name(model, obj, i, prefix):
    import mujoco

    n = mujoco.mj_id2name(model, obj, int(i))
    n = n if n else f"{prefix}{int(i)}"
    return "".join(c if (c.isalnum() or c in "_-.") else "_" for c in n)


def geom_surface(model, g: int):
    """(vertices, faces) of geom ``g`` in its own frame, for display; None when it has no
    surface to show (height fields, SDFs). Planes become a square of their size (or 2 m)."""
    import mujoco

    from .geometry import load_mesh
    from .sim.scene import geom_mesh_spec

    T = mujoco.mjtGeom
    t = int(model.geom_type[g])
    if t == T.mjGEOM_PLANE:
        sx, sy = (float(s) if s > 0 else 1.0 for s in model.geom_size[g][:2])
        v = np.array([[-sx, -sy, 0], [sx, -sy, 0], [sx, sy, 0], [-sx, sy, 0]], float)
        return v, np.array([[0, 1, 2], [0, 2, 3]])
    try:
        spec, _ = geom_mesh_spec(model, g)
    except ValueError:
        return None
    if isinstance(spec, tuple):
        return spec
    tm = load_mesh(spec, check_size=False)
    return np.asarray(tm.vertices), np.asarray(tm.faces)


def _xyzw(q_wxyz):
    q = np.asarray(q_wxyz, float)
    return [q[1], q[2], q[3], q[0]]


class RerunLogger:
    """Write a rerun recording of a simulation with sound (see the module docstring).

    Parameters
    ----------
    path : str | os.PathLike
        The ``.rrd`` file to write. The recording goes to a temporary file beside it that
        :meth:`close` renames into place, so an earlier recording of the same name survives
        an interrupted run (:meth:`abort`, or an exception inside ``with``) untouched. The
        take's audio is held in memory until :meth:`close` (it is logged as one waveform,
        spectrogram and WAV asset): about 4 bytes per sample and microphone.
    model : mujoco.MjModel
    sim : AudioSimulator, optional
        Its ``scene`` names the microphones, its ``event_log`` gives the impact texts and its
        ``sample_rate`` the audio rate. Without it give ``sample_rate`` and ``mic_names``.
    sample_rate : int, optional
    mic_names : list[str], optional
    pose_rate_hz : float
        Rate of body poses and contacts on the timeline (default 120 Hz; ``None``: every step).
    force_scale : float
        Arrow length per newton [m/N].
    full_scale_pa : float | None
        Pressure written as full scale into the ``AssetAudio`` WAV (16-bit PCM). ``None``
        (default): peak-normalised to -1 dBFS, so quiet scenes are audible in the viewer.
    n_fft, hop : int
        Spectrogram STFT (Hann window; default 1024 and 256 samples at 48 kHz).
    meshes : bool
        Log the geoms' meshes (``False``: poses, contacts and sound only).
    geom_groups : tuple[int]
        Geom groups whose meshes are shown (MuJoCo's default visible groups 0-2).
    application_id : str
    """

    def __init__(self, path, model, sim=None, *, sample_rate=None, mic_names=None, pose_rate_hz=120.0,
                 force_scale=0.002, full_scale_pa=None, n_fft=1024, hop=256, meshes=True, geom_groups=(0, 1, 2),
                 application_id="mjsound"):
        import mujoco
        import rerun as rr

        self._rr = rr
        self._mj = mujoco
        self.path = os.fspath(path)
        self.model = model
        self.sim = sim
        self.sample_rate = int(sample_rate if sample_rate is not None else sim.sample_rate)
        if mic_names is None:
            mic_names = list(sim.channel_names) if sim is not None else ["listener"]
        self.mic_names = [("".join(c if (c.isalnum() or c in "_-.") else "_" for c in n) or f"mic{i}")
                          for i, n in enumerate(mic_names)]
        # contact microphones [m/s^2]: their own entities, audio/contact/<site>
        self._contact = [int(c) for c in getattr(sim, "contact_channels", ()) if int(c) < len(self.mic_names)]
        for c in self._contact:
            self.mic_names[c] = "contact/" + self.mic_names[c]
        self.pose_dt = 0.0 if not pose_rate_hz else 1.0 / float(pose_rate_hz)
        self.force_scale = float(force_scale)
        self.full_scale_pa = full_scale_pa
        self.n_fft, self.hop = int(n_fft), int(hop)
        from .io import temp_beside

        self.rec = rr.RecordingStream(application_id)
        fd, self._tmp = temp_beside(self.path, ".rrd")
        os.close(fd)
        self.rec.save(self._tmp)
        self._blocks = []
        self._n_start = None  # absolute sample index of the first logged sample
        self._n_next = None
        self._t_next_pose = -np.inf
        self._n_events = 0
        self._closed = False
        self._body_names = [_name(model, mujoco.mjtObj.mjOBJ_BODY, b, "body") for b in range(model.nbody)]
        self._geom_names = [_name(model, mujoco.mjtObj.mjOBJ_GEOM, g, "geom") for g in range(model.ngeom)]
        bodies = set(self._body_names)
        for g in range(model.ngeom):  # world geoms live at world/<geom>: keep clear of body paths
            if model.geom_bodyid[g] == 0 and self._geom_names[g] in bodies:
                self._geom_names[g] = "geom_" + self._geom_names[g]
        self._moving = [b for b in range(1, model.nbody) if model.body_weldid[b] != 0 or model.body_mocapid[b] >= 0]
        self._static_done = False
        self._pose_buf = {"t": [], "xpos": [], "xquat": [], "cpos": [], "cforce": []}
        self._meshes = bool(meshes)
        self._groups = set(int(x) for x in geom_groups)

    # ------------------------------------------------------------------ static scene
    def _log_static(self, data) -> None:
        rr, m = self._rr, self.model
        rec = self.rec
        moving = set(self._moving)
        for b in range(m.nbody):
            if b not in moving:
                path = "world" if b == 0 else f"world/{self._body_names[b]}"
                if b:
                    rec.log(path, rr.Transform3D(translation=data.xpos[b], quaternion=_xyzw(data.xquat[b])), static=True)
        if self._meshes:
            for g in range(m.ngeom):
                if int(m.geom_group[g]) not in self._groups:
                    continue
                surf = geom_surface(m, g)
                if surf is None:
                    continue
                v, f = surf
                b = int(m.geom_bodyid[g])
                base = "world" if b == 0 else f"world/{self._body_names[b]}"
                path = f"{base}/{self._geom_names[g]}"
                rgba = np.clip(np.asarray(m.geom_rgba[g]) * 255, 0, 255).astype(np.uint8)
                rec.log(path, rr.Transform3D(translation=m.geom_pos[g], quaternion=_xyzw(m.geom_quat[g])), static=True)
                rec.log(path, rr.Mesh3D(vertex_positions=np.asarray(v, np.float32), triangle_indices=np.asarray(f, np.uint32),
                                        albedo_factor=rgba), static=True)
        self._static_done = True

    # ------------------------------------------------------------------ per step
    def log_step(self, data, block=None, n_start=None) -> None:
        """Log the state after one ``mj_step`` and the audio block that step produced.

        Parameters
        ----------
        data : mujoco.MjData
        block : (channels, n) array [Pa], optional
            The step's audio (``AudioSimulator.step()``'s return value).
        n_start : int, optional
            Absolute sample index of the block's first sample (sample n is at ``n / fs``).
            Default: continues the previous block; the first block starts at
            ``sim.clock.n - n`` when ``sim`` is known, else at ``ceil((time - timestep) fs)``.
        """
        rr, mj, m = self._rr, self._mj, self.model
        rec = self.rec
        if not self._static_done:
            self._log_static(data)
        t = float(data.time)
        if block is not None:
            block = np.asarray(block, np.float32)
            n = block.shape[1]
            if n_start is None:
                if self._n_next is not None:
                    n_start = self._n_next
                elif self.sim is not None and hasattr(self.sim, "clock"):
                    n_start = int(self.sim.clock.n) - n
                else:
                    n_start = int(np.ceil((t - float(m.opt.timestep)) * self.sample_rate - 1e-9))
            if self._n_start is None:
                self._n_start = int(n_start)
            elif n_start != self._n_next:  # a gap or an overlap: pad / cut so samples stay at n / fs
                gap = int(n_start) - self._n_next
                if gap > 0:
                    self._blocks.append(np.zeros((block.shape[0], gap), np.float32))
                else:
                    block = block[:, -gap:]
            self._blocks.append(block)
            self._n_next = int(n_start) + n
        # impact events (exact times)
        if self.sim is not None:
            log = self.sim.event_log
            for ev in log[self._n_events:]:
                time, kind, g1, g2, val = ev
                if kind != "impact":
                    continue
                rec.set_time("sim_time", duration=float(time))
                rec.log("events", rr.TextLog(f"impact {self._geom_names[g1]} / {self._geom_names[g2]}: "
                                             f"{float(val):.3g} N s", level="INFO"))
            self._n_events = len(log)
        if t + 1e-12 < self._t_next_pose:
            return
        self._t_next_pose = t + self.pose_dt
        # poses and contacts are buffered and sent as columns (one rerun call per entity per
        # POSE_CHUNK samples instead of one per entity per sample)
        buf = self._pose_buf
        buf["t"].append(t)
        buf["xpos"].append(np.array(data.xpos[self._moving]))
        buf["xquat"].append(np.array(data.xquat[self._moving]))
        nc = int(data.ncon)
        if nc:
            pos = np.array(data.contact.pos[:nc])
            frames = np.array(data.contact.frame[:nc]).reshape(nc, 3, 3)
            f6 = np.zeros(6)
            forces = np.empty((nc, 3))
            for i in range(nc):
                mj.mj_contactForce(m, data, i, f6)
                forces[i] = frames[i].T @ f6[:3]
            buf["cpos"].append(pos)
            buf["cforce"].append(forces * self.force_scale)
        else:
            buf["cpos"].append(np.zeros((0, 3)))
            buf["cforce"].append(np.zeros((0, 3)))
        if len(buf["t"]) >= self.POSE_CHUNK:
            self._send_poses()

    #: Pose / contact samples buffered before they are sent (an interrupted run keeps all but
    #: the last chunk; ``close`` sends the rest).
    POSE_CHUNK = 100

    def _send_poses(self) -> None:
        buf = self._pose_buf
        if not buf["t"]:
            return
        rr, rec = self._rr, self.rec
        index = [rr.TimeColumn("sim_time", duration=np.asarray(buf["t"]))]
        xpos = np.stack(buf["xpos"])  # (T, bodies, 3)
        xquat = np.stack(buf["xquat"])[..., [1, 2, 3, 0]]  # MuJoCo wxyz -> rerun xyzw
        for j, b in enumerate(self._moving):
            rec.send_columns(f"world/{self._body_names[b]}", indexes=index,
                             columns=rr.Transform3D.columns(translation=xpos[:, j], quaternion=xquat[:, j]))
        lengths = np.array([len(p) for p in buf["cpos"]])
        P = np.concatenate(buf["cpos"])
        F = np.concatenate(buf["cforce"])
        k = len(P)
        rec.send_columns("world/contacts/points", indexes=index,
                         columns=rr.Points3D.columns(positions=P, radii=np.full(k, 0.004),
                                                     colors=np.tile(np.array([255, 80, 40], np.uint8), (k, 1)))
                         .partition(lengths))
        rec.send_columns("world/contacts/forces", indexes=index,
                         columns=rr.Arrows3D.columns(origins=P, vectors=F,
                                                     colors=np.tile(np.array([255, 200, 0], np.uint8), (k, 1)))
                         .partition(lengths))
        for v in buf.values():
            v.clear()

    # ------------------------------------------------------------------ audio
    @property
    def audio(self) -> np.ndarray:
        """Everything logged so far, (channels, n) float32 [Pa]."""
        if not self._blocks:
            return np.zeros((len(self.mic_names), 0), np.float32)
        return np.concatenate(self._blocks, axis=1)

    def wav_bytes(self, audio=None) -> bytes:
        """The take as 16-bit PCM WAV bytes (full-scale mapping: see ``full_scale_pa``)."""
        import soundfile as sf

        from .synth.output import normalize_peak, to_full_scale

        a = self.audio if audio is None else np.asarray(audio)
        if self._contact:  # contact channels at their own full scale
            from .synth.contact_mic import DEFAULT_CONTACT_FULL_SCALE
            from .synth.output import DEFAULT_FULL_SCALE_PA

            a = a.copy()
            a[self._contact] *= (self.full_scale_pa or DEFAULT_FULL_SCALE_PA) / DEFAULT_CONTACT_FULL_SCALE
        if self.full_scale_pa is None:
            x = normalize_peak(a)
        else:
            x, _ = to_full_scale(a, self.full_scale_pa)
        buf = io.BytesIO()
        sf.write(buf, np.ascontiguousarray(x.T), self.sample_rate, subtype="PCM_16", format="WAV")
        return buf.getvalue()

    def _spectrogram(self, x):
        n_fft = self.n_fft
        while n_fft > 16 and n_fft > len(x):
            n_fft //= 2
        hop = max(1, min(self.hop, n_fft // 2))
        if len(x) < n_fft:
            x = np.pad(x, (0, n_fft - len(x)))
        frames = 1 + (len(x) - n_fft) // hop
        idx = np.arange(n_fft)[None, :] + hop * np.arange(frames)[:, None]
        win = np.hanning(n_fft + 1)[:-1]
        spec = np.abs(np.fft.rfft(x[idx] * win, axis=1)) * (2.0 / win.sum())
        return (20 * np.log10(np.maximum(spec, 2e-5 * 1e-3) / 2e-5)).T.astype(np.float32), hop  # (freq, time)

    def close(self) -> None:
        """Log the waveforms, spectrograms, the audio asset and the blueprint; finish the file
        and move it into place (atomic)."""
        if self._closed:
            return
        self._closed = True
        from .io import commit_temp, discard_temp

        try:
            self._log_take()
            self._finish_stream()
            commit_temp(self._tmp, self.path)
        except BaseException:
            discard_temp(self._tmp)
            raise

    def _log_take(self) -> None:
        rr = self._rr
        import rerun.blueprint as rrb

        self._send_poses()

        rec = self.rec
        audio = self.audio
        fs = self.sample_rate
        n0 = self._n_start or 0
        names = list(self.mic_names)
        if audio.shape[0] != len(names):
            names = [f"mic{i}" for i in range(audio.shape[0])]
        views = []
        if audio.shape[1]:
            n = n0 + np.arange(audio.shape[1], dtype=np.int64)
            t = ((n * 1_000_000_000 + fs // 2) // fs).astype("timedelta64[ns]")  # exact n / fs, rounded to ns
            for c, name in enumerate(names):
                rec.send_columns(f"audio/{name}/waveform", indexes=[rr.TimeColumn("sim_time", duration=t)],
                                 columns=rr.Scalars.columns(scalars=audio[c].astype(np.float64)))
                unit = "m/s^2" if name.startswith("contact/") else "Pa"
                rec.log(f"audio/{name}/waveform", rr.SeriesLines(names=f"{name} [{unit}]"), static=True)
                S, hop = self._spectrogram(audio[c].astype(np.float64))
                rec.log(f"audio/{name}/spectrogram", rr.Tensor(S[::-1], dim_names=["freq_hz_desc", "time"]), static=True)
                views.append(rrb.TensorView(origin=f"audio/{name}/spectrogram", name=f"{name} spectrogram (dB)"))
            rec.set_time("sim_time", duration=n0 / fs)
            rec.log("audio/take", rr.AssetAudio(contents=self.wav_bytes(audio), media_type="audio/wav"))
        blueprint = rrb.Blueprint(
            rrb.Horizontal(
                rrb.Spatial3DView(origin="world", name="scene"),
                rrb.Vertical(
                    rrb.AudioView(origin="audio/take", name="audio"),
                    rrb.TimeSeriesView(origin="audio", contents=[f"audio/{n}/waveform" for n in names], name="waveform"),
                    *views,
                    rrb.TextLogView(origin="events", name="impacts"),
                ),
            ),
        )
        rec.send_blueprint(blueprint)

    def _finish_stream(self) -> None:
        self.rec.flush()
        try:
            self.rec.disconnect()
        except Exception:  # pragma: no cover - older/newer SDKs
            pass

    def abort(self) -> None:
        """Stop recording and discard the temporary file; ``path`` is left as it was."""
        if self._closed:
            return
        self._closed = True
        from .io import discard_temp

        try:
            self._finish_stream()
        finally:
            discard_temp(self._tmp)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, *exc):
        if exc_type is None:
            self.close()
        else:
            self.abort()
        return False


def log_sonify(rrd, scene_xml, **sonify_kwargs) -> dict:
    """:func:`mjsound.sim.rollout.sonify` that also writes a rerun recording to ``rrd``.

    Same arguments and return value as ``sonify`` (plus ``"rrd"`` in the summary). Every
    simulated / replayed physics step is logged with the audio block it produced, through
    ``AudioSimulator.on_block`` (``sonify`` itself knows nothing of rerun).
    """
    from .sim.rollout import sonify

    holder = {}

    def on_block(sim, block, n0):
        log = holder.get("log")
        if log is None:
            log = holder["log"] = RerunLogger(rrd, sim.model, sim=sim)
        log.log_step(sim.data, block, n_start=n0)  # n0: absolute sample index (n / fs)

    try:
        summary = sonify(scene_xml, on_block=on_block, **sonify_kwargs)
    except BaseException:
        if "log" in holder:
            holder["log"].abort()
        raise
    if "log" in holder:
        holder["log"].close()
    summary["rrd"] = os.fspath(rrd)
    return summary
