"""`AudioSimulator`: sound for a running MuJoCo simulation, MuJoCo contacts -> synthesizer ->
audio blocks.

The simulator sets up what sounds (the scene's objects in a synthesizer, how each geom drives
them, clicks and contact microphones, image microphones) and offers the stepping API:
:meth:`AudioSimulator.step` after each of the caller's ``mj_step``, :meth:`AudioSimulator.flush`
for the samples of ``step(render=False)``, :meth:`AudioSimulator.advance` (mjsound steps the
physics itself) and :meth:`AudioSimulator.run`. Each goes through its step driver
(:class:`.driver.StepDriver`: the one way into the step kernel, the clock and the per-step
state); ``docs/design.md`` draws the data flow and lists the state records.

Time alignment (:mod:`.clock`): the step from ``t_k`` to ``t_{k+1}`` returns exactly the
samples ``ceil(t_k fs) <= n < ceil(t_{k+1} fs)``; events found in it are timed at ``t_k``
(:mod:`mjsound.sim.contacts`), never earlier than what was already rendered, so the block is
rendered right after they are queued and nothing is delayed. A step more than one timestep
after the last one read, or none, raises; time going backwards is a reset behind the
simulator's back, and it resets itself. Rendering can wait: ``step(render=False)`` queues a
step's impacts and sustained-contact noise (generated at once) and
:meth:`AudioSimulator.flush` renders every pending sample in one synthesizer call. Impacts
sound exactly the same; a sliding contact's gains follow its point once per render instead
of every ``sustained_block_s``.
"""

from __future__ import annotations

import math
import os
import warnings

import numpy as np

from ..synth.constants import ROLL_PATCH_M, ROLL_ROUGHNESS, SLIDE_GRAIN_M, SLIDE_ROUGHNESS
from ..synth.dispatch import EntryPoint
from ..synth.pulse import compliance
from .channels import ImpactPulses, attach_contact_mics, channel_layout, needs_pulses
from .clock import SampleClock
from .contacts import ContactReader
from .drive import sync_poses
from .driver import StepDriver
from .listener import ListenerMethods
from .records import DRIVE_PARAMS, SOUND, DriveState
from .reports import SimulatorReports
from .scene import SoundScene, geom_contact_radius
from .first_compile import notice_first_compile
from .rooms import scene_images, scene_room, set_image_responses
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
    materials, microphones, budget_modes, quality, progress, masses
        Passed to :meth:`SoundScene.from_model` when ``scene`` is None (``masses``: ``"mujoco"``,
        the default, gives the sound's objects MuJoCo's masses; ``"material"`` keeps every
        material's density; :mod:`.scene_masses`).
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
        ``order``) instead of the scene's planes, and its late reverberant tail follows
        (:attr:`tail`; ``Room(..., tail=False)``: none).
    actuators : str | dict, optional
        Actuator noise (:mod:`.actuators`, ``docs/actuators.md``): a preset for every
        actuator (``"servo"``, ``"harmonic"``, ``"qdd"``, ``"none"``) or ``{actuator name:
        preset}``, over the MJCF custom texts ``mjsound-actuator:NAME``. Default: off unless a
        preset is named.
    fused : bool
        Let :meth:`advance` call ``mj_step`` from numba (default; where this MuJoCo build's
        C functions and struct layout check out). False (or the environment variable
        ``MJSOUND_FUSED=0``): every ``mj_step`` and contact read goes through the bindings.

    Attributes
    ----------
    driver : StepDriver
        The step driver (:class:`.driver.StepDriver`): the step kernel of :attr:`data`, the
        clock, the samples pending, the event log.
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
        masses: str | None = None,
        actuators=None,
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
                                          progress=progress, masses=masses)
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
        #: the room's late reverberant tail (:class:`mjsound.synth.reverb.LateTail`), or None
        self.tail = None
        if not np.any(np.asarray(self.data.geom_xmat)):
            mujoco.mj_kinematics(model, self.data)  # poses for add_object (state is unchanged)
        air = np.asarray(scene.mic_positions, np.float64).reshape(-1, 3)
        room = scene_room(model, reflections, room)
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
            if room is not None:  # (calibrated for sources where the sounding objects are now)
                where = [self.data.geom_xpos[s.geom_id] for s in scene.sounding]
                self.tail = room.late_tail(self.images, air, self.sample_rate,
                                           np.mean(where, axis=0) if where else None)
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
                                    self.sample_rate, clicks=clicks, active=makes_pulses, images=self.images)
        # a thin hollow shell's wall bends under the contact: the modes get the clicks' pulse length
        # (struck: an object analysed as a hollow wall only; a solid's modes keep Hertz's time)
        shells = self.pulses.state.model.geoms["shell_compliance"]
        self._sound["other_shell"] = shells
        for g, s in self._sounding.items():
            if getattr(s, "mass_rule", "") == "hollow":
                self._sound["shell"][g] = shells[g]
        prm[0]["pulses"] = int(self.pulses.active)
        # (the kernel mixes the track into a float32 block; a float64 one is mixed after its conversion)
        prm[0]["mix_pulses"] = int(self.pulses.active and self.synth is not None and self.synth.dtype == np.float32)
        self._follow = None
        self._mic_sites = np.asarray(list(scene.mic_site_ids) + self._contact_sites, np.int64)  # (contact: unused)
        self._sites_move = bool(scene.mic_site_ids) and scene.mics_move
        notice_first_compile()
        use_c = fused and os.environ.get("MJSOUND_FUSED", "1") != "0"
        self._drive = None
        self._sidx = np.full((16, 2), -1, np.int64)
        self._sync_poses_call = EntryPoint(sync_poses)
        self._sidx_epoch = None
        self._sidx_reader = None  # (the reader state _sidx was sized for)
        #: the step driver (:class:`.driver.StepDriver`): the step kernel of :attr:`data` and the
        #: per-step state (clock, samples pending, event log)
        self.driver = StepDriver(model, self.data, self.reader, self.sample_rate, synth=self.synth,
                                 pulses=self.pulses, drive_state=self._drive_state if self.synth is not None else None,
                                 make_streams=self._make_streams, amplitude_error=self._amplitude_error,
                                 reset_sound=self._reset_sound, n_channels=self.n_channels, images=self.images,
                                 n_air=self.n_air, tail=self.tail, keep_events=self.keep_events, use_c=use_c,
                                 owner=self)
        self.actuators = None
        if self.synth is not None:
            from .actuators import ActuatorSound, actuator_config

            config = actuator_config(model, actuators)
            if config:
                self.actuators = ActuatorSound(self, config)
                self.driver.drives = self.actuators
        if use_c and not self.driver.fused:
            warnings.warn("mjsound: substeps run through Python (MuJoCo's C functions or struct layout could not be "
                          "checked)", RuntimeWarning, stacklevel=user_stacklevel())
        self.reset(clear_reader=True)

    # ------------------------------------------------------------------ state
    def reset(self, clear_reader: bool = True) -> None:
        """Silence all ringing, forget contact state and re-anchor the clock at ``data.time``
        (a following listener moves to its body's current position)."""
        self.driver.reset(clear_reader)

    def _reset_sound(self, clear_reader: bool) -> None:
        """Silence the synthesizer and the pulses, microphones to where they are, forget the
        contact state when asked (the driver's resets)."""
        self.pulses.reset(0)
        if self.tail is not None:
            self.tail.reset()
        if self.synth is not None:
            self.synth.reset()
            if self._follow is not None:
                self._update_mics()
        if clear_reader:
            self.reader.reset()

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
        self.model, self.data = model, data
        self.reader.model = model
        if not np.any(np.asarray(data.geom_xmat)):
            mujoco.mj_kinematics(model, data)  # (poses for the moving objects and microphones)
        self.driver.bind(model, data)

    @property
    def clock(self) -> SampleClock:
        """The sample clock (:class:`.clock.SampleClock`)."""
        return self.driver.clock

    @property
    def steps(self) -> int:
        """Physics steps read since the last reset."""
        return self.driver.steps

    @property
    def samples(self) -> int:
        """Samples counted since the last reset."""
        return self.driver.samples

    @property
    def seconds_contacts(self) -> float:
        """Seconds spent reading steps the caller took (:meth:`step`) since the last reset."""
        return self.driver.seconds_contacts

    @property
    def seconds_synth(self) -> float:
        """Seconds spent rendering in Python calls since the last reset."""
        return self.driver.seconds_synth

    @property
    def on_block(self):
        """Optional observer ``on_block(sim, block, n0)`` called with every rendered audio
        block and its first absolute sample index (e.g. :class:`mjsound.rerun_log.RerunLogger`);
        :meth:`reset` clears it."""
        return self.driver.on_block

    @on_block.setter
    def on_block(self, fn) -> None:
        self.driver.on_block = fn

    @property
    def geom_objects(self) -> np.ndarray:
        """Synthesizer object index each geom excites (-1: silent), (ngeom,) int64."""
        return self._sound["obj"]

    @property
    def object_names(self) -> dict:
        """``{geom id: name of the sounding object it excites}`` for the sounding geoms."""
        return self._names

    @property
    def regain_samples(self) -> int:
        """Samples a sustained stream is driven ahead of the clock (its regain block)."""
        return int(self._drive_prm[0]["regain"])

    # ------------------------------------------------------------------ the kernel's inputs
    def _drive_state(self, reader_state) -> DriveState:
        """The drive's arrays (:class:`.records.DriveState`) for the reader's current state
        ``reader_state``, rebuilt when one was replaced."""
        synth = self.synth
        if self._sidx_epoch != synth.streams_epoch:  # the synthesizer forgot its streams
            self._sidx[:] = -1  # (in place: the packed kernel state stays valid)
            self._sidx_epoch = synth.streams_epoch
        rs = reader_state
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
        self._sync_poses_call((self._drive_state(self.reader.state()), self.driver.views, self.synth.kernel_state()))

    def _make_streams(self, missing, rows) -> None:
        """A stream for each (row, side) without one: key (geom1, geom2, struck geom)."""
        synth = self.synth
        for r, side in missing:
            row = rows[r]
            g1, g2, slot = int(row["g1"]), int(row["g2"]), int(row["slot"])
            g = g2 if side == 0 else g1
            j = synth.stream((g1, g2, g), self._names[g])
            if slot >= len(self._sidx):
                self._drive_state(self.reader.state())  # (grows the table to the reader's slots)
            self._sidx[slot, side] = j

    def _amplitude_error(self, impacts) -> ValueError:
        """The synthesizer's error for ``impacts`` whose modal amplitude is out of range."""
        objs = self._sound["obj"][np.concatenate([impacts["g1"], impacts["g2"]])]
        return self.synth.amplitude_error(objs[objs >= 0])

    # ------------------------------------------------------------------ stepping
    def step(self, render: bool = True) -> np.ndarray | None:
        """Process the step just taken by ``mj_step``; return its audio block.

        Call it after every ``mj_step``. ``data.time`` must be one timestep after the last
        step read: more (steps taken without calling this: their contacts were never read) or
        no advance at all (this ``MjData`` is no longer the one stepped: :meth:`rebind`)
        raises ``RuntimeError``; backwards is a reset (``mj_resetData``): the simulator resets
        itself, the samples counted before come out first.

        Parameters
        ----------
        render : bool
            False: read the step's contacts and queue its sound, but render later (in
            :meth:`flush`, one synthesizer call for many steps: an env's own substep loop calls
            ``step(render=False)`` after each ``mj_step`` and :meth:`flush` once per env step).
            The step returns None then. The audio is the same except that a sliding contact's
            gains follow its point once per render.

        Returns
        -------
        (channels, n) float32 array | None
            Sound pressure at each microphone [Pa] for the samples ``t_k <= n/fs < t_{k+1}``
            (with ``render=True``: the samples of earlier unrendered steps come first).
        """
        return self.driver.substeps(1, render, False, True)

    def flush(self) -> np.ndarray:
        """Render the samples of the steps taken with ``step(render=False)`` or
        ``advance(n, render=False)`` (possibly none): ``(channels, n)`` float32 pressure [Pa]."""
        return self.driver.flush()

    def advance(self, nstep: int = 1, render: bool = True) -> np.ndarray | None:
        """``mj_step`` then read it, ``nstep`` times, in one numba call (the step kernel calls
        ``mj_step`` itself where MuJoCo's C functions and struct layout check out: ``fused``).

        Parameters
        ----------
        nstep : int
            Physics steps (a gymnasium env's ``frame_skip``).
        render : bool
            Return the audio of these steps (and of earlier unrendered ones first), rendered in
            the same numba call; False: return None, the audio comes from :meth:`flush`.

        Returns
        -------
        (channels, n) float32 array [Pa] | None
        """
        return self.driver.substeps(int(nstep), render)

    @property
    def steps_per_render(self) -> int:
        """Physics steps per rendered block in :meth:`run` (``render_block_s``)."""
        return max(1, int(round(self.render_block_s / float(self.model.opt.timestep))))

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
        if self.driver.pending:
            blocks.append(self.flush())
        for i in range(0, nsteps, every):  # render_block_s of steps at a time
            m = min(every, nsteps - i)
            if callback is None:
                blocks.append(self.driver.substeps(m))  # (one numba call, the render included)
            else:
                for _ in range(m):
                    callback(self.model, self.data)
                    self._mj.mj_step(self.model, self.data)
                    self.driver.substeps(1, False, False, True)
                blocks.append(self.flush())
        if not blocks:
            return np.zeros((self.n_channels, 0), np.float32)
        return blocks[0] if len(blocks) == 1 else np.concatenate(blocks, axis=1)

    # ------------------------------------------------------------------ deprecated
    def substeps(self, nstep: int, render: bool = False) -> None:
        """Deprecated: :meth:`advance` ``(nstep, render=False)`` (the audio from :meth:`flush`)."""
        warnings.warn("AudioSimulator.substeps(n) is deprecated: use advance(n, render=False) and flush(), or "
                      "advance(n) for the block", DeprecationWarning, stacklevel=2)
        self.driver.substeps(int(nstep), False, bool(render))

    def stepper(self):
        """Deprecated: :meth:`advance`."""
        warnings.warn("AudioSimulator.stepper() is deprecated: call advance(n, render=False) and flush()",
                      DeprecationWarning, stacklevel=2)
        return lambda nstep: self.driver.substeps(int(nstep), False, True)

    def replay_step(self, n0: int, n1: int, t0: float, t1: float, origin: int | None = None, render: bool = True):
        """Deprecated: :meth:`.driver.StepDriver.replay` (``sim.driver.replay``)."""
        warnings.warn("AudioSimulator.replay_step is deprecated: use sim.driver.replay(n0, n1, t0, t1, origin, "
                      "render) (mjsound.sonify replays rollouts)", DeprecationWarning, stacklevel=2)
        return self.driver.replay(n0, n1, t0, t1, origin, render)
