"""`AudioSimulator`: the per-step driver, MuJoCo contacts -> synthesizer -> audio blocks.

Time alignment (:mod:`.clock`): the step from ``t_k`` to ``t_{k+1}`` returns exactly the
samples ``ceil(t_k fs) <= n < ceil(t_{k+1} fs)``; events found in it are timed at ``t_k``
(:mod:`mjsound.sim.contacts`), never earlier than what was already rendered, so the block is
rendered right after they are queued and nothing is delayed. If ``data.time`` jumps forward
(or the timestep changes) the clock re-anchors at the new time; if it goes backwards, the
simulation was reset behind the simulator's back and it resets itself.

Every path (:meth:`AudioSimulator.step`, :meth:`AudioSimulator.substeps`, rollout replay)
runs the same step kernel (:mod:`.step`); ``docs/design.md`` draws the data flow and lists
the state records. Rendering can wait: ``step(render=False)`` queues a step's impacts and
sustained-contact noise (generated at once) and :meth:`AudioSimulator.flush` renders every
pending sample in one synthesizer call. Impacts sound exactly the same; a sliding contact's
gains follow its point once per render instead of every ``sustained_block_s``.
"""

from __future__ import annotations

import math
import os
import time as _time
import warnings

import numpy as np

from ..synth.constants import ROLL_PATCH_M, ROLL_ROUGHNESS, SLIDE_GRAIN_M, SLIDE_ROUGHNESS
from ..synth.dispatch import EntryPoint
from ..synth.kernels import RENDERED
from ..synth.pulse import compliance
from .clock import SampleClock
from .contacts import ContactReader
from .drive import sync_poses
from .records import DRIVE_PARAMS, NOT_RENDERED, SOUND, DriveState
from .listener import ListenerMethods
from .reports import SimulatorReports
from .runner import StepKernel
from .scene import SoundScene, geom_contact_radius
from .channels import ImpactPulses, attach_contact_mics, channel_layout, needs_pulses
from .images import fold
from .rooms import scene_images, set_image_responses
from .step import PULSES, AMPLITUDE, CLOCK_JUMP, RING, STREAMS
from .substeps import make_substeps
from .warmup import notice_first_compile
from ..user_frame import user_stacklevel

__all__ = ["AudioSimulator", "SampleClock"]

class AudioSimulator(ListenerMethods, SimulatorReports):
    """Sound for a running MuJoCo simulation, one audio block per physics step.

    Parameters
    ----------
    model : mujoco.MjModel | str
        The model (or an MJCF path).
    data : mujoco.MjData, optional
        Its data (created when omitted).
    scene : SoundScene, optional
        A prepared scene; built with :meth:`SoundScene.from_model` otherwise.
    sample_rate : int
        Audio sample rate [Hz].
    materials, microphones, budget_modes, quality, progress
        Passed to :meth:`SoundScene.from_model` when ``scene`` is None.
    synth_kwargs : dict, optional
        Extra keyword arguments for :class:`mjsound.synth.synthesizer.Synthesizer`.
    reader_kwargs : dict, optional
        Extra keyword arguments for :class:`ContactReader` (thresholds).
    sustained : bool
        Drive sliding and rolling sound (default True).
    keep_events : int
        :attr:`event_log` keeps the first this many events.
    sustained_block_s : float
        A sliding / rolling contact's gains follow its point at most this often [s].
    render_block_s : float
        :meth:`run` and :meth:`advance` render once per this much simulated time [s]
        (default 10 ms: one synthesizer call per 10 steps of 1 ms, which is most of the
        per-step cost saved; 0 renders every step). :meth:`step` renders every call unless
        told otherwise.
    clicks, contact_mics : bool, list[str] | None
        Impacts click (:mod:`.clicks`); contact microphone sites (:mod:`.channels`, :attr:`channel_names`).
    reflections : bool | dict
        The scene's planes reflect (default True): each air microphone also hears every
        object from its mirror image in each plane welded to the world, through the plane's
        surface (:mod:`.images`, :mod:`.surfaces`; ``docs/rooms.md``). False: free field (the
        sound before reflections, bit for bit). A dict ``{plane name: surface or None}`` sets
        the named planes' surfaces (a name in :data:`.surfaces.SURFACES`, one absorption
        coefficient or six per octave band; None: that plane does not reflect).
    room : Room, optional
        A room around the scene (:class:`.rooms.Room`): its walls reflect (images up to its
        ``order``) instead of the scene's planes.
    fused : bool
        Let :meth:`substeps` call ``mj_step`` from numba (default; where this MuJoCo build's
        C functions and struct layout check out). False (or the environment variable
        ``MJSOUND_FUSED=0``): every ``mj_step`` and contact read goes through the bindings.

    Attributes
    ----------
    reader : ContactReader
        The contact reader (its impact records: :meth:`ContactReader.newest_records`).
    pulses : ImpactPulses
        Impacts' clicks and contact-microphone pulses (:meth:`ImpactPulses.audible_bodies`).

    Notes
    -----
    Call :meth:`step` right after every ``mj_step`` (or let :meth:`advance` / :meth:`run` do
    the stepping). Each call returns ``(channels, n)`` float32 pascals: exactly the samples
    of the step just taken. ``events`` counts what was emitted. If ``data.time`` goes
    backwards (an environment reset the simulator was not told about), the ringing is cleared
    and counting restarts there, as :meth:`reset` does (the samples before it still come out).

    Examples
    --------
    >>> sim = AudioSimulator(model, data)            # doctest: +SKIP
    >>> for _ in range(1000):                         # doctest: +SKIP
    ...     mujoco.mj_step(model, data)
    ...     block = sim.step()
    """

    def __init__(
        self,
        model,
        data=None,
        scene: SoundScene | None = None,
        sample_rate: int = 48000,
        materials: dict | None = None,
        microphones=None,
        budget_modes: int | None = None,
        quality: str = "default",
        progress: bool = True,
        synth_kwargs: dict | None = None,
        reader_kwargs: dict | None = None,
        sustained: bool = True,
        keep_events: int = 100_000,
        sustained_block_s: float = 0.004,
        render_block_s: float = 0.01,
        clicks: bool = True,
        contact_mics=None,
        fused: bool = True,
        reflections=True,
        room=None,
    ):
        import mujoco

        self._mj = mujoco
        if not isinstance(model, mujoco.MjModel):
            if scene is not None:
                model = scene.model
            else:
                model = mujoco.MjModel.from_xml_path(os.fspath(model))
        self.model = model
        self.data = data if data is not None else mujoco.MjData(model)
        self._opt = model.opt  # (a view into the model: timestep changes show through it)
        if scene is None:
            scene = SoundScene.from_model(model, materials=materials, microphones=microphones,
                                          budget_modes=budget_modes, sample_rate=sample_rate, quality=quality,
                                          progress=progress)
        self.scene = scene
        self.sample_rate = int(sample_rate)
        self.sustained = bool(sustained)
        self.keep_events = int(keep_events)
        self.sustained_block_s = float(sustained_block_s)
        self.render_block_s = float(render_block_s)
        if not (math.isfinite(self.render_block_s) and self.render_block_s >= 0):
            raise ValueError(f"render_block_s={render_block_s!r} must be a duration >= 0 in seconds")
        restitution = [m.restitution if m is not None else None for m in scene.geom_material]
        self.reader = ContactReader(model, restitution=restitution, **(reader_kwargs or {}))
        self._sounding = scene.by_geom()
        self._names = {g: s.name for g, s in self._sounding.items()}
        self._radius = np.array([geom_contact_radius(model, g) for g in range(model.ngeom)])
        # the mass each geom strikes with: its body's subtree (inf: welded to the world)
        self._other_mass = self.reader.bodies["tree_mass"][np.asarray(model.geom_bodyid)]
        self._contact_sites, self.n_air, self.channel_names, self.contact_channels = channel_layout(model, scene, contact_mics)
        self.n_channels = len(self.channel_names)  # the air microphones, then the contact microphones
        self.synth = None
        if not np.any(np.asarray(self.data.geom_xmat)):
            mujoco.mj_kinematics(model, self.data)  # poses for add_object (state is unchanged)
        air = np.asarray(scene.mic_positions, np.float64).reshape(-1, 3)
        self.images = scene_images(model, self.data, scene, air, reflections, room)
        n_img = len(self.images)
        self._row_channel, self._row_affine = self.images.rows(self.n_air, self.n_channels)
        # how each geom sounds: synthesizer object index (-1: silent, or no modes to drive) and
        # what Hertz's contact time takes of it struck and striking; the moving objects with their geoms
        self._sound = np.zeros(model.ngeom, SOUND)
        self._sound["obj"] = -1
        self._sound["other_mass"] = self._other_mass
        self._sound["other_radius"] = self._radius
        self._sound["other_compliance"] = [compliance(m) for m in scene.geom_material]
        moving = {}
        prm = np.zeros(1, DRIVE_PARAMS)
        makes_pulses = needs_pulses(model, self._contact_sites, clicks)  # (clicks or contact microphones)
        if scene.sounding or makes_pulses:
            from ..synth.synthesizer import Synthesizer

            p = prm[0]
            p["rough_slide"], p["rough_roll"] = SLIDE_ROUGHNESS, ROLL_ROUGHNESS
            p["len_slide"], p["len_roll"] = SLIDE_GRAIN_M, ROLL_PATCH_M
            self.synth = Synthesizer(sample_rate=self.sample_rate, microphones=np.vstack([air, self.images.positions(air)]),
                                     **dict(synth_kwargs or {}))
            for s in scene.sounding:
                self.synth.add_object(s.name, s.model, position=np.array(self.data.geom_xpos[s.geom_id]),
                                      rotation=np.array(self.data.geom_xmat[s.geom_id]).reshape(3, 3))
            attach_contact_mics(self.synth, scene, model, self.data, self._contact_sites)
            set_image_responses(self.synth, self.n_air, self.images)
            self.synth.on_regain = self._sync_poses
            for g, s in self._sounding.items():
                idx = self.synth.object_index(s.name)
                if s.dynamic:
                    moving[idx] = s.geom_id  # the object's anchor: its model lives in that geom's frame
                if self.synth.n_modes(s.name):
                    self._sound[g]["obj"] = idx
                    r = float(self._radius[g])
                    terms = self.synth.hertz_terms(s.name, r if np.isfinite(r) else None)
                    for field, value in zip(("mass", "radius", "compliance"), terms):
                        self._sound[field][g] = value
        self._dyn_obj = np.array(sorted(moving), np.int64)
        self._dyn_geoms = np.array([moving[i] for i in self._dyn_obj.tolist()], np.int64)
        self._drive_prm = prm
        prm[0]["regain"] = max(1, int(round(self.sustained_block_s * self.sample_rate)))
        prm[0]["sustained"] = int(self.sustained)
        self.pulses = ImpactPulses(model, scene.geom_material, self._radius, self.n_air + n_img, self._contact_sites,
                                    self.sample_rate, clicks=clicks, active=makes_pulses)
        prm[0]["pulses"] = int(self.pulses.active)
        # (the kernel mixes the track into a float32 block; a float64 one is mixed after its conversion)
        prm[0]["mix_pulses"] = int(self.pulses.active and self.synth is not None and self.synth.dtype == np.float32)
        self._follow = None
        self._mic_sites = np.asarray(list(scene.mic_site_ids) + self._contact_sites, np.int64)  # (contact: unused)
        self._sites_move = bool(scene.mic_site_ids) and scene.mics_move
        self.clock = SampleClock(self.sample_rate, float(model.opt.timestep), float(self.data.time))
        notice_first_compile()
        use_c = fused and os.environ.get("MJSOUND_FUSED", "1") != "0"
        self._use_c = use_c
        self._kernel = StepKernel(model, self.data, self.reader, clock=self.clock.rec, use_c=use_c)
        self._fused = use_c and self._kernel.can_step
        if use_c and not self._fused:
            warnings.warn("mjsound: substeps run through Python (MuJoCo's C functions or struct layout could not be "
                          "checked)", RuntimeWarning, stacklevel=user_stacklevel())
        self._drive = None
        self._sidx = np.full((16, 2), -1, np.int64)
        self._sync_poses_call = EntryPoint(sync_poses)
        self._sidx_epoch = None
        self._sidx_reader = None  # (the reader state _sidx was sized for)
        self._held = []  # blocks rendered before an automatic reset, returned by the next render
        self._substeps = make_substeps(self)
        self.reset(clear_reader=True)

    # ------------------------------------------------------------------ state
    def reset(self, clear_reader: bool = True) -> None:
        """Silence all ringing, forget contact state and re-anchor the clock at ``data.time``
        (a following listener moves to its body's current position)."""
        self._reset_at(float(self.data.time), clear_reader)
        self._held = []

    def _reset_at(self, t_start: float, clear_reader: bool = True, keep_observer: bool = False) -> None:
        self.pulses.reset(0)
        if self.synth is not None:
            self.synth.reset()
            if self._follow is not None:
                self._update_mics()
        if clear_reader:
            self.reader.reset()
        self.clock.anchor(float(self.model.opt.timestep), t_start)
        self._origin = self.clock.n  # synth sample 0 is absolute sample n = origin
        self._impacts_base = self.reader.n_impacts_made
        self._sustained_base = self.reader.sustained_steps
        # event log: entries and LOG arrays, expanded when read (event_log)
        self._log = []
        self._log_pending = []
        self._n_logged = 0
        self.samples = 0
        self.steps = 0
        #: optional observer ``on_block(sim, block, n0)`` called with every step's audio block
        #: and its first absolute sample index (e.g. :class:`mjsound.rerun_log.RerunLogger`)
        self.on_block = getattr(self, "on_block", None) if keep_observer else None
        self.seconds_contacts = 0.0
        self.seconds_synth = 0.0
        self._pending = 0  # samples stepped but not rendered yet (step(render=False))
        self._pending_n0 = self.clock.n
        self._ready = None  # a block substeps(render=True) rendered, returned by the next flush

    @property
    def _geom_obj(self) -> np.ndarray:
        """Synthesizer object index each geom excites (-1: silent), (ngeom,) int64."""
        return self._sound["obj"]

    @property
    def _origin(self) -> int:
        """Absolute sample of the synthesizer's sample 0."""
        return int(self.clock.rec[0]["origin"])

    @_origin.setter
    def _origin(self, n: int) -> None:
        self.clock.rec[0]["origin"] = n

    def _clock_jump(self) -> None:
        """``data.time`` or the timestep no longer match the count. A new timestep: restart
        counting at this step (the step just taken ends at ``data.time``). Backwards in time is
        a reset the simulator was not told about (``mj_resetData`` between episodes): the
        ringing is cleared and counting restarts (the samples counted so far are rendered first
        and come out with the next block). Time that did not advance or advanced by more than
        one step raises (:meth:`_time_error`): the contacts of skipped steps were never read,
        and data that is not stepped any more gives no sound to read."""
        c = self.clock
        dt = float(self._opt.timestep)
        t_new = float(self.data.time) - dt
        if self.data.time < c.time_at(c.k) - 0.25 * c.timestep:  # backwards
            if self._ready is not None:
                self._held.append(self._ready)
                self._ready = None
            if self._pending:
                self._held.append(self._render_pending())
            self._reset_at(t_new, keep_observer=True)
            return
        if dt == c.timestep:
            raise self._time_error()
        n_prev = c.n
        c.anchor(dt, t_new)
        self._origin += c.n - n_prev

    def _time_error(self) -> RuntimeError:
        """The error for a step whose ``data.time`` is not one timestep after the last one read."""
        c = self.clock
        t, t_last, dt = float(self.data.time), c.time_at(c.k), c.timestep
        if abs(t - t_last) <= 0.25 * dt:
            return RuntimeError(
                f"mjsound: data.time ({t:.9g} s) has not advanced since the last step read: this simulator's MjData "
                "is not the one being stepped (an env that rebuilt its MjModel/MjData on reset, e.g. robosuite's hard "
                "reset or a dm_control composer env: call sim.rebind(model, data) with the new ones), or step() "
                "was called without an mj_step before it")
        return RuntimeError(
            f"mjsound: data.time advanced by {t - t_last:.6g} s ({(t - t_last) / dt:.4g} timesteps of {dt:g} s) since "
            "the last step read: the contacts of the skipped steps were never read. Call sim.step() after every "
            "mj_step (in an env's own substep loop: sim.step(render=False) after each mj_step, then sim.flush() "
            "once per env step), or let sim.advance(n) step the physics; after setting data.time yourself, call "
            "sim.reset()")

    def rebind(self, model, data=None) -> None:
        """Follow a new ``MjModel`` / ``MjData`` of the same scene (an env that rebuilds them
        on reset: robosuite's hard reset, a dm_control composer env's new ``Physics``).

        The analysed scene, the synthesizer and everything ringing are kept; the clock is
        anchored at the new ``data.time`` with the output's sample count continuing where it
        was (samples pending from the old data stay pending: the next render returns them).
        Call :meth:`reset` as well to silence the ringing and restart at the new time, as an
        env reset usually does.

        Parameters
        ----------
        model : mujoco.MjModel
            The new model: the same geoms and bodies as the simulator's (same counts, geom
            types and geom-to-body map).
        data : mujoco.MjData, optional
            Its data (created when omitted).

        Raises
        ------
        ValueError
            When ``model`` is not of the same scene (then build a new ``AudioSimulator``,
            passing ``scene=`` of an equal model reuses the analysed objects).
        """
        mujoco = self._mj
        if not isinstance(model, mujoco.MjModel):
            raise TypeError(f"rebind: model must be a mujoco.MjModel, got {type(model).__name__}")
        if data is None:
            data = mujoco.MjData(model)
        old = self.model
        for what in ("ngeom", "nbody", "nv", "nsite"):
            if getattr(model, what) != getattr(old, what):
                raise ValueError(f"rebind: the new model has {what}={getattr(model, what)}, the simulator's "
                                 f"{getattr(old, what)}: not the same scene; build a new AudioSimulator for it")
        for what in ("geom_bodyid", "geom_type"):
            if not np.array_equal(getattr(model, what), getattr(old, what)):
                raise ValueError(f"rebind: the new model's {what} differs from the simulator's: not the same scene; "
                                 "build a new AudioSimulator for it")
        self.model, self.data, self._opt = model, data, model.opt
        self.reader.model = model
        if not np.any(np.asarray(data.geom_xmat)):
            mujoco.mj_kinematics(model, data)  # (poses for the moving objects and microphones)
        self._kernel = StepKernel(model, data, self.reader, clock=self.clock.rec, use_c=self._use_c)
        self._fused = self._use_c and self._kernel.can_step
        self._substeps = make_substeps(self)
        c = self.clock
        n_prev = c.n
        c.anchor(float(model.opt.timestep), float(data.time))
        self._origin += c.n - n_prev

    # ------------------------------------------------------------------ the kernel's inputs
    def _drive_state(self, reader_state=None) -> DriveState:
        """The drive's arrays (:class:`.records.DriveState`), rebuilt when one was replaced;
        ``reader_state``: the reader's current :meth:`ContactReader.state` (asked when None)."""
        synth = self.synth
        if synth is not None and self._sidx_epoch != synth.streams_epoch:  # the synthesizer forgot its streams
            self._sidx[:] = -1  # (in place: the kernel's entry point stays valid)
            self._sidx_epoch = synth.streams_epoch
        rs = self.reader.state() if reader_state is None else reader_state
        if rs is not self._sidx_reader:  # (a new reader state: its slot table may have grown)
            slots = len(rs.pairs)  # (a stream row for every slot the reader can hold)
            if slots > len(self._sidx):
                grown = np.full((max(2 * len(self._sidx), slots), 2), -1, np.int64)
                grown[: len(self._sidx)] = self._sidx
                self._sidx = grown
                self._drive = None
            self._sidx_reader = rs
        if self._drive is None or self._drive.pulses is not self.pulses.state:
            mode, source, rows, offsets, affine = self._mic_config()
            self._drive_prm[0]["mic_mode"], self._drive_prm[0]["mic_source"] = mode, source
            self._drive = DriveState(self._drive_prm, self._sound, self._sidx, rows, offsets, affine,
                                     self._dyn_geoms, self._dyn_obj, self.pulses.state)
        return self._drive

    def _sync_poses(self) -> None:
        """Microphones and every moving sounding object to where they are now, before an
        event needs them (``Synthesizer.on_regain`` for the streams' gains). An exploding
        simulation's non-finite poses are skipped: those keep the last good one."""
        self._sync_poses_call((self._drive_state(), self._kernel.views, self.synth.kernel_state()))

    # ------------------------------------------------------------------ stepping
    def step(self, render: bool = True) -> np.ndarray | None:
        """Process the step just taken by ``mj_step``; return its audio block.

        Parameters
        ----------
        render : bool
            False: read the step's contacts and queue its sound, but render later (in
            :meth:`flush`, one synthesizer call for many steps: e.g. once per env step of a
            gymnasium env with ``frame_skip``). The step returns None then. The audio is the
            same except that a sliding contact's gains follow its point once per render.

        Returns
        -------
        (channels, n) float32 array | None
            Sound pressure at each microphone [Pa] for the samples ``t_k <= n/fs < t_{k+1}``
            (with ``render=True``: the samples of earlier unrendered steps come first).
        """
        c = self.clock
        dt = c.timestep
        if self._opt.timestep != dt or abs(self.data.time - (c.t_start + (c.k + 1) * dt)) > 0.25 * dt:
            self._clock_jump()
        if self.synth is None:
            n0, n1 = c.advance()
            self._count(n0, n1)
        else:
            n0 = c.n
            tc = _time.perf_counter()
            if self._read_step():
                self.seconds_contacts += _time.perf_counter() - tc
            else:
                c.advance()
            self._count(n0, c.n)
        return self._render_pending() if render else None

    def _read_step(self, explicit=None) -> bool:
        """Read the contacts of the step just taken and queue its sound (one kernel call;
        ``explicit``: see :meth:`.runner.StepKernel.call`); False when nothing touches and no
        impact record is open (the step is only counted, the clock not advanced)."""
        self.synth.poses_current = False  # (a physics step was taken)
        if self.data.ncon == 0 and not self.reader.any_open:  # nothing to read
            self.reader.count_quiet_step()
            return False
        self._call(1, call_step=False, explicit=explicit)
        self.synth.poses_current = False
        return True

    def replay_step(self, n0: int, n1: int, t0: float, t1: float, origin: int | None = None, render: bool = True):
        """Process a recorded step (``data`` set to its frame): samples ``[n0, n1)`` and times
        ``[t0, t1)`` given by the caller, the clock unused; ``origin``: absolute sample of the
        synthesizer's sample 0 (None: unchanged). Queues its sound; renders what is pending if
        ``render``."""
        if origin is not None:
            self._origin = int(origin)
        self._count(n0, n1)
        if self.synth is not None:
            self._read_step(explicit=(t0, t1, n0, n1))
        return self._render_pending() if render else None

    def substeps(self, nstep: int, render: bool = False) -> None:
        """``mj_step`` then :meth:`step` ``(render=False)``, ``nstep`` times (a gymnasium env's
        ``frame_skip``); the audio comes from :meth:`flush`.

        The substeps run in one numba call (the step kernel calls ``mj_step`` itself) whenever
        this simulator can (``fused=True``, MuJoCo's C functions and struct layout checked,
        the clock fits 64-bit integers); the result is the same as the loop in Python, bit
        for bit. ``render=True``: the same call also renders every pending sample (when the
        synthesizer has no Python forcing sources), which :meth:`flush` then returns: the
        same audio as rendering in :meth:`flush`, one numba call fewer."""
        self._substeps(int(nstep), bool(render))

    def stepper(self):
        """``stepper()(nstep)``: :meth:`substeps` ``(nstep, render=True)`` as a plain function,
        for a caller that calls it every env step (:class:`mjsound.wrappers.AudioObservation`'s
        hook): the same call, one Python call fewer."""
        return self._substeps  # (render defaults to True there)

    def _count_segment(self) -> None:
        """Count the substeps the kernel finished since ``_seg`` (clock step and sample)."""
        k0, n0 = self._seg
        c = self.clock
        k = c.k
        n = c.sample_at(k)
        if k > k0:
            self._count(n0, n, k - k0)
        self._seg = (k, n)

    def _call(self, nstep: int, call_step: bool, explicit=None, block=None) -> None:
        """One call of the step kernel (and its hand-backs), then collect what it produced;
        ``block``: render the pending samples into it (:meth:`.runner.StepKernel.call`)."""
        synth = self.synth
        self._kernel.call(self._drive_state, synth.kernel_state, nstep, call_step, explicit, self._log_room(),
                          self._on_stop, synth, synth.render_target, block)
        self._collect()

    def _kernel_state(self) -> tuple:
        """The step kernel's state now (:func:`.step.advance`'s tuple; asked again after every
        hand-back: an owner may have replaced a record)."""
        k, reader, synth = self._kernel, self.reader, self.synth
        rs = reader.state()
        return (k.mj, k.views, rs, reader.buffers, k.clock, self._drive_state(rs), synth.kernel_state(), k.run,
                synth.render_target())

    def _log_room(self) -> int:
        """Event log entries the kernel may still write."""
        return max(0, self.keep_events - self._n_logged)

    def _collect(self) -> None:
        """Take the kernel's event log entries and clamped-force counts (the reader warns); the
        impact records wait in the reader's rows until read."""
        f = self._kernel.f
        self.reader.report_clamped()
        n_log = int(f["n_log"][0])
        if n_log:
            self._log_pending.append(self.reader.buffers.log[:n_log].copy())
            self._n_logged += n_log
            f["n_log"][0] = 0
            f["log_limit"][0] = self._log_room()

    def _on_stop(self, reason: int) -> None:
        """What the step kernel hands back: see :mod:`.step`."""
        run = self._kernel.run[0]
        buf = self.reader.buffers
        if reason == STREAMS:
            self._make_streams(buf.missing[: int(run["n_missing"])].tolist(), buf.sustained)
        elif reason == RING:
            self.synth.grow_stream_ring(int(run["need"]))
        elif reason == CLOCK_JUMP:
            run["render"] = 0  # (the pending samples change: flush renders them)
            self._collect()
            self.pulses.flush()  # (the substeps' pulses so far, before the clock moves)
            self._count_segment()
            self._clock_jump()
            self._seg = (self.clock.k, self.clock.n)
        elif reason == PULSES:  # the pulse rows are full: to the track, and room for this substep's
            self.pulses.flush()
            self.pulses.reserve(int(run["n_imp"]))
        elif reason == AMPLITUDE:
            self._collect()
            self.pulses.flush()
            imp = buf.impacts[: int(run["need"])]
            objs = self._sound["obj"][np.concatenate([imp["g1"], imp["g2"]])]
            raise self.synth.amplitude_error(objs[objs >= 0])

    def _make_streams(self, missing, rows) -> None:
        """A stream for each (row, side) without one: key (geom1, geom2, struck geom)."""
        synth = self.synth
        for r, side in missing:
            row = rows[r]
            g1, g2, slot = int(row["g1"]), int(row["g2"]), int(row["slot"])
            g = g2 if side == 0 else g1
            j = synth.stream((g1, g2, g), self._names[g])
            if slot >= len(self._sidx):
                self._drive_state()  # (grows the table to the reader's slots)
            self._sidx[slot, side] = j

    # ------------------------------------------------------------------ rendering
    def flush(self) -> np.ndarray:
        """Render the samples of the steps taken with ``step(render=False)`` (possibly none):
        ``(channels, n)`` float32 pressure [Pa]."""
        ready = self._ready
        if ready is None:
            return self._render_pending()
        self._ready = None  # (rendered by substeps(render=True))
        if not self._pending and not self._held:
            return ready
        return np.concatenate([ready, self._render_pending()], axis=1)

    def _count(self, n0: int, n1: int, steps: int = 1) -> None:
        """Count ``steps`` physics steps of samples ``[n0, n1)``, not rendered yet."""
        if self._pending == 0:
            self._pending_n0 = n0
        self._pending += n1 - n0
        self.steps += steps
        self.samples += n1 - n0

    def _render_pending(self) -> np.ndarray:
        n = self._pending
        n0 = self._pending_n0 if n else self.clock.n  # (_count sets _pending_n0 when samples start pending)
        self._pending = 0
        if self.synth is None:
            block = np.zeros((self.n_channels, n), dtype=np.float32)
        else:
            tc = _time.perf_counter()
            block = self.pulses.mix(self.synth.render(n))  # (never NaN) plus the clicks and contact pulses
            if len(self.images):
                block = fold(block, self.n_air, self.images)  # (image rows into their microphones' channels)
            self.seconds_synth += _time.perf_counter() - tc
        return self._deliver(block, n0)

    def _deliver(self, block: np.ndarray, n0: int) -> np.ndarray:
        """A rendered block (first absolute sample ``n0``) to the observer, after the blocks
        held back by an automatic reset."""
        if self.on_block is not None:
            self.on_block(self, block, n0)
        if self._held:
            block = np.concatenate([*self._held, block], axis=1)
            self._held = []
        return block

    @property
    def steps_per_render(self) -> int:
        """Physics steps per rendered block in :meth:`run` / :meth:`advance` (``render_block_s``)."""
        return max(1, int(round(self.render_block_s / float(self.model.opt.timestep))))

    def advance(self, nstep: int = 1) -> np.ndarray:
        """``mj_step`` then :meth:`step`, ``nstep`` times; the blocks concatenated."""
        return self.run(int(nstep) * float(self.model.opt.timestep), nsteps=int(nstep))

    def run(self, duration: float, callback=None, nsteps: int | None = None) -> np.ndarray:
        """Simulate ``duration`` seconds (``round(duration / timestep)`` steps) with sound.

        Parameters
        ----------
        duration : float
            Simulated time [s].
        callback : callable, optional
            ``callback(model, data)`` before every ``mj_step`` (e.g. to set controls).
        nsteps : int, optional
            Number of steps (overrides ``duration``).

        Returns
        -------
        (channels, n) float32 array [Pa], ``n = ceil(t_end fs) - ceil(t_start fs)``.
        """
        if nsteps is None:
            nsteps = int(round(float(duration) / float(self.model.opt.timestep)))
        every = self.steps_per_render
        blocks = []
        if self._pending:
            blocks.append(self.flush())
        for i in range(0, nsteps, every):  # render_block_s of steps at a time
            m = min(every, nsteps - i)
            if callback is None:
                self.substeps(m, render=True)  # (one numba call, the render included)
            else:
                for _ in range(m):
                    callback(self.model, self.data)
                    self._mj.mj_step(self.model, self.data)
                    self.step(render=False)
            blocks.append(self.flush())
        if not blocks:
            return np.zeros((self.n_channels, 0), np.float32)
        return blocks[0] if len(blocks) == 1 else np.concatenate(blocks, axis=1)
