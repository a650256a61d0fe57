"""How an environment steps MuJoCo: found, followed and hooked so that every substep is heard.

An env wrapper needs three things from the env it wraps: the ``MjModel`` / ``MjData`` it
steps *now* (composer builds a new ``Physics`` at resets, robosuite a new ``MjSim`` at every
hard reset), how much time one env step simulates (the audio window), and a hook that reads
the contacts after every physics substep. Each route below gives them for one family:

==========================  ==================================================  =====================================
route                       env                                                 hooked (on the instance)
==========================  ==================================================  =====================================
:class:`GymMujocoStepping`  gymnasium ``MujocoEnv`` (Ant-v5, Meta-World, ...)    ``_step_mujoco_simulation(ctrl, n)``
:class:`RoboticsStepping`   gymnasium-robotics ``MujocoRobotEnv`` (Fetch, ...)   ``_mujoco_step(action)``
:class:`MyoStepping`        MyoSuite 3 ``MyoGymnasiumEnv``                       ``_step_physics(nstep)``
:class:`DmPhysicsStepping`  a dm_control env's ``physics`` (suite, composer,    ``physics.step(nstep)``
                            gym-aloha's ``AlohaEnv._env``)
:class:`MjSimStepping`      robosuite's ``MjSim`` (robosuite 1.5, LIBERO)        ``sim.step()``, ``sim.step2()``
==========================  ==================================================  =====================================

:func:`find_stepping` looks at the unwrapped gymnasium env and, one level down, at its
attributes (an inner env that shares its model: gymnasium-robotics' mazes; a dm_control
environment: gym-aloha; a robosuite env: ``robosuite.wrappers.GymWrapper``).

The hooks run the env's own MuJoCo calls and tell the audio simulator after each completed
step: the fused ``StepDriver.substeps`` where the route is a plain run of ``mj_step``
(gymnasium, gymnasium-robotics, dm_control without legacy stepping), else
``sim.step(render=False)`` after each of the env's own steps, the own-loop route, whose audio
``sim.flush()`` returns once per env step (:meth:`mjsound.env_audio.EnvAudio.end_step`).
"""

from __future__ import annotations

import weakref

import numpy as np

__all__ = ["Stepping", "GymMujocoStepping", "RoboticsStepping", "MyoStepping", "DmPhysicsStepping", "MjSimStepping",
           "find_stepping", "steps_of"]


class Stepping:
    """One env's stepping route (module docstring). Subclasses set :attr:`route` and implement
    :meth:`current`, :meth:`step_dt` and :meth:`_install`; :meth:`remove` restores the env."""

    #: what is hooked, for messages
    route = ""

    def __init__(self, owner):
        self.owner = owner
        self._hooked = []  # (weak reference to the object, attribute name) of the installed hooks

    def current(self) -> tuple:
        """``(MjModel, MjData)`` the env steps now."""
        raise NotImplementedError

    def step_dt(self) -> float | None:
        """Simulated time of one env step [s], from the env's own attributes (None: unknown)."""
        raise NotImplementedError

    def install(self, sim) -> None:
        """Hook the env's current physics so that ``sim`` hears every substep (the previous
        hooks are removed first: after a rebuilt physics the old objects may be gone)."""
        self.remove()
        self._install(sim)

    def _install(self, sim) -> None:
        raise NotImplementedError

    def _set(self, obj, name, fn) -> None:
        if isinstance(obj, weakref.ProxyTypes):  # (composer hands out its physics as a proxy)
            obj = obj.__init__.__self__  # (a bound method's instance: the object itself)
        setattr(obj, name, fn)
        self._hooked.append((weakref.ref(obj), name))

    def remove(self) -> None:
        """Give the hooked objects their own methods back (those still alive)."""
        for ref, name in self._hooked:
            obj = ref()
            if obj is not None and name in vars(obj):
                delattr(obj, name)
        self._hooked = []


class GymMujocoStepping(Stepping):
    """gymnasium's ``MujocoEnv``: ``_step_mujoco_simulation(ctrl, n_frames)`` becomes
    ``data.ctrl[:] = ctrl``, ``n_frames`` fused ``mj_step`` + contact reads, then
    ``mj_rnePostConstraint`` as gymnasium does."""

    route = "gymnasium MujocoEnv._step_mujoco_simulation"

    def current(self):
        return self.owner.model, self.owner.data

    def step_dt(self):
        dt = getattr(self.owner, "dt", None)
        return float(dt) if dt is not None else None

    def _install(self, sim):
        import mujoco

        env = self.owner
        model, data = env.model, env.data
        # mj_step + contact read, n times, and the env step's audio rendered, in one numba call
        # (kept: EnvAudio.end_step's flush returns that block); the driver's method, entered
        # directly (an env step's Python: each frame costs)
        substeps = sim.driver.substeps
        # (data.ctrl read once: each read of it makes a new view; its memory lives as the MjData)
        ctrl_now, rne_post_constraint = data.ctrl, mujoco.mj_rnePostConstraint

        def _step_mujoco_simulation(ctrl, n_frames):
            ctrl_now[:] = ctrl
            substeps(n_frames, False, True)  # (nstep, render, keep)
            rne_post_constraint(model, data)

        self._set(env, "_step_mujoco_simulation", _step_mujoco_simulation)


class RoboticsStepping(GymMujocoStepping):
    """gymnasium-robotics' ``MujocoRobotEnv``: ``_mujoco_step(action)`` (``mj_step(model, data,
    nstep=n_substeps)``) becomes ``n_substeps`` fused steps."""

    route = "gymnasium-robotics MujocoRobotEnv._mujoco_step"

    def _install(self, sim):
        env = self.owner
        substeps = sim.driver.substeps

        def _mujoco_step(action):
            substeps(env.n_substeps, False, True)  # (nstep, render, keep: as above)

        self._set(env, "_mujoco_step", _mujoco_step)


class MyoStepping(GymMujocoStepping):
    """MyoSuite 3's ``MyoGymnasiumEnv``: ``_step_physics(nstep=None)`` (``mj_step(model, data,
    nstep or frame_skip)``, then ``mj_forward``) becomes that many fused steps, then
    ``mj_forward`` as MyoSuite does. One env step simulates ``frame_skip`` timesteps."""

    route = "MyoSuite MyoGymnasiumEnv._step_physics"

    def step_dt(self):
        return self.owner.frame_skip * float(self.owner.model.opt.timestep)

    def _install(self, sim):
        import mujoco

        env = self.owner
        model, data = env.model, env.data
        substeps, forward = sim.driver.substeps, mujoco.mj_forward

        def _step_physics(nstep=None):
            substeps(int(env.frame_skip if nstep is None else nstep), False, True)  # (nstep, render, keep)
            forward(model, data)

        self._set(env, "_step_physics", _step_physics)


class DmPhysicsStepping(Stepping):
    """A dm_control environment (``rl.control.Environment``, ``composer.Environment``) or an
    object holding one: its ``physics.step(nstep)`` becomes the same MuJoCo calls with every
    completed step read (dm_control's legacy step: ``mj_step2``, ``nstep - 1`` ``mj_step``,
    ``mj_step1``; else ``nstep`` ``mj_step``). The physics is looked up at every
    :meth:`current` (composer replaces it at resets and frees the old one: only a weak
    reference to a hooked one is kept)."""

    route = "dm_control Physics.step"

    def current(self):
        physics = self.owner.physics
        return physics.model.ptr, physics.data.ptr

    def step_dt(self):
        return float(self.owner.control_timestep())

    def _install(self, sim):
        import mujoco

        physics = self.owner.physics
        model, data = physics.model.ptr, physics.data.ptr
        rk4 = mujoco.mjtIntegrator.mjINT_RK4.value
        substeps = sim.driver.substeps  # (nstep, render, keep: the block rendered and kept for flush)

        def step(nstep: int = 1) -> None:
            nstep = int(nstep)
            with physics.check_invalid_state():
                if getattr(physics, "legacy_step", False):
                    if model.opt.integrator != rk4:
                        mujoco.mj_step2(model, data)  # completes the step mj_step1 began
                        sim.step(render=False)
                        if nstep > 1:
                            substeps(nstep - 1, False, True)
                    else:
                        substeps(nstep, False, True)
                    mujoco.mj_step1(model, data)
                else:
                    substeps(nstep, False, True)  # (rendered in the same numba call; end_step flushes)

        self._set(physics, "step", step)


class MjSimStepping(Stepping):
    """robosuite's ``MjSim`` (``env.sim``; robosuite 1.5, LIBERO): the env steps in its own loop
    (``step1``, controller, ``step2`` per substep; or ``forward``, controller, ``step``), so
    ``sim.step()`` and ``sim.step2()`` are hooked to tell the audio simulator after each
    completed step (``step(render=False)``, the own-loop route). robosuite's default
    ``hard_reset=True`` builds a new ``MjSim`` at every reset: :meth:`current` reads
    ``env.sim`` each time. Needs :func:`mjsound.compat.patch_robosuite` on mujoco 4."""

    route = "robosuite MjSim.step / MjSim.step2"

    def current(self):
        sim = self.owner.sim
        return sim.model._model, sim.data._data

    def step_dt(self):
        return float(self.owner.control_timestep)

    def _install(self, sim):
        mjsim = self.owner.sim
        own_step, own_step2 = mjsim.step, mjsim.step2
        heard = sim.step

        def step(*args, **kwargs):
            own_step(*args, **kwargs)
            heard(render=False)

        def step2():
            own_step2()
            heard(render=False)

        self._set(mjsim, "step", step)
        self._set(mjsim, "step2", step2)


class _HeardMujoco:
    """A stand-in for the ``mujoco`` module in one env module: every name is MuJoCo's but
    ``mj_step``, which after each step on a hooked ``MjData`` tells that data's simulator
    (``sim.step(render=False)``)."""

    def __init__(self, mujoco):
        self._mujoco = mujoco
        self._sims = {}  # id(MjData) -> (MjData, AudioSimulator)

    def __getattr__(self, name):
        return getattr(self._mujoco, name)

    def mj_step(self, m, d, nstep=1):
        hooked = self._sims.get(id(d))
        if hooked is None or hooked[0] is not d:
            return self._mujoco.mj_step(m, d, nstep)
        step, heard = self._mujoco.mj_step, hooked[1].step
        for _ in range(int(nstep)):
            step(m, d)
            heard(render=False)


class ModuleStepping(Stepping):
    """An env that steps in its own loop with ``mujoco.mj_step(model, data)`` calls written in
    the modules of its class and base classes (lerobot-env-so101's
    ``MujocoGymEnv.apply_action``): each such module's global ``mujoco`` becomes a stand-in
    whose ``mj_step`` on this env's ``data`` is followed by ``sim.step(render=False)`` (the
    own-loop route; other data pass through untouched). The env step's length comes from its
    own attributes (:func:`steps_of`)."""

    def __init__(self, owner, modules):
        super().__init__(owner)
        self.modules = list(modules)
        self.route = f"mujoco.mj_step calls in {', '.join(m.__name__ for m in self.modules)}"

    def current(self):
        return self.owner.model, self.owner.data

    def step_dt(self):
        return None

    def _install(self, sim):
        data = self.owner.data
        for module in self.modules:
            view = vars(module)["mujoco"]
            if not isinstance(view, _HeardMujoco):
                view = _HeardMujoco(view)
                module.mujoco = view
            view._sims[id(data)] = (data, sim)
        self._view_key = id(data)

    def remove(self):
        for module in self.modules:
            view = vars(module).get("mujoco")
            if isinstance(view, _HeardMujoco):
                view._sims.pop(getattr(self, "_view_key", None), None)
                if not view._sims:
                    module.mujoco = view._mujoco


def _stepping_modules(env) -> list:
    """The modules of ``env``'s class and its bases whose global ``mujoco`` is MuJoCo's and
    whose source calls ``mujoco.mj_step`` (none of gymnasium's or mjsound's)."""
    import inspect
    import sys

    import mujoco

    found = []
    for cls in type(env).__mro__:
        module = sys.modules.get(cls.__module__)
        if module is None or module in found or module.__name__.split(".")[0] in ("gymnasium", "mjsound", "builtins",
                                                                                   "typing"):
            continue
        glob = vars(module).get("mujoco")
        if glob is mujoco or isinstance(glob, _HeardMujoco):
            try:
                if "mujoco.mj_step(" in inspect.getsource(module):
                    found.append(module)
            except (OSError, TypeError):
                continue
    return found


def _is_mjsim(obj) -> bool:
    """A robosuite ``MjSim`` (its ``model._model`` / ``data._data`` are MuJoCo's)."""
    import mujoco

    return (callable(getattr(obj, "step2", None)) and isinstance(getattr(getattr(obj, "model", None), "_model", None), mujoco.MjModel)
            and isinstance(getattr(getattr(obj, "data", None), "_data", None), mujoco.MjData))


def _is_dm_env(obj) -> bool:
    """A dm_control environment: ``physics.model.ptr`` / ``physics.data.ptr`` are MuJoCo's."""
    import mujoco

    try:
        physics = obj.physics
        return (isinstance(physics.model.ptr, mujoco.MjModel) and isinstance(physics.data.ptr, mujoco.MjData)
                and callable(getattr(physics, "step", None)) and callable(getattr(obj, "control_timestep", None)))
    except (AttributeError, ReferenceError):
        return False


def _route_of(env) -> Stepping | None:
    """The route of ``env`` itself, or None."""
    import mujoco

    if callable(getattr(env, "_step_mujoco_simulation", None)):
        return GymMujocoStepping(env)
    if callable(getattr(env, "_mujoco_step", None)) and isinstance(getattr(env, "n_substeps", None), (int, np.integer)) \
            and isinstance(getattr(env, "model", None), mujoco.MjModel) and isinstance(getattr(env, "data", None), mujoco.MjData):
        return RoboticsStepping(env)
    if callable(getattr(env, "_step_physics", None)) and isinstance(getattr(env, "frame_skip", None), (int, np.integer)) \
            and isinstance(getattr(env, "model", None), mujoco.MjModel) and isinstance(getattr(env, "data", None), mujoco.MjData):
        return MyoStepping(env)
    if _is_dm_env(env):
        return DmPhysicsStepping(env)
    if _is_mjsim(getattr(env, "sim", None)) and getattr(env, "control_timestep", None) is not None:
        return MjSimStepping(env)
    return None


def find_stepping(uw) -> Stepping | None:
    """The stepping route of a gymnasium env's unwrapped env (module docstring), or None.

    Looks at ``uw`` itself, then at its attributes: an inner gymnasium env that shares its
    ``model`` and ``data`` (gymnasium-robotics' ``AntMazeEnv.ant_env``), a dm_control
    environment (gym-aloha's ``AlohaEnv._env``), a robosuite env (``GymWrapper.env``); last,
    an env with ``model`` / ``data`` whose class's module calls ``mujoco.mj_step`` itself
    (:class:`ModuleStepping`).
    """
    route = _route_of(uw)
    if route is not None:
        return route
    route = _route_of_inner(uw)
    if route is not None:
        return route
    import mujoco

    if isinstance(getattr(uw, "model", None), mujoco.MjModel) and isinstance(getattr(uw, "data", None), mujoco.MjData):
        modules = _stepping_modules(uw)
        if modules:
            return ModuleStepping(uw, modules)
    return None


def _route_of_inner(uw) -> Stepping | None:
    """The route of an object ``uw`` holds (:func:`find_stepping`), or None."""
    model, data = getattr(uw, "model", None), getattr(uw, "data", None)
    inner = dict(vars(uw))
    if "env" not in inner and getattr(type(uw), "__getattr__", None) is not None:
        try:  # (robosuite's GymWrapper keeps its env as .env and forwards attributes to it)
            inner["env"] = uw.env
        except AttributeError:
            pass
    for value in inner.values():
        if value is uw or value is None or isinstance(value, (int, float, str, bytes, np.ndarray)):
            continue
        import gymnasium as gym

        if isinstance(value, gym.Env):
            iu = value.unwrapped
            if model is not None and getattr(iu, "model", None) is model and getattr(iu, "data", None) is data:
                route = _route_of(iu)
                if route is not None:
                    return route
            continue
        try:
            route = _route_of(value)
        except Exception:  # (an attribute that fails when looked at, e.g. a dead weak proxy: not a route)
            continue
        if isinstance(route, (DmPhysicsStepping, MjSimStepping)):
            return route
    return None


def steps_of(uw, route: Stepping | None) -> tuple:
    """Simulated time of one env step [s] from the env's own attributes, and where it came from:
    the route's (``dt``, ``control_timestep``), else the unwrapped env's ``dt``,
    ``control_timestep()``, ``control_dt``, ``frame_skip`` or ``n_substeps`` times the model's
    timestep. ``(None, "")``: none of these (the caller asks for ``window_s``)."""
    name = type(uw).__name__
    if route is not None:
        dt = route.step_dt()
        if dt is not None:
            return float(dt), f"{route.route}'s env step"
    for attr in ("dt", "control_timestep", "control_dt"):
        dt = getattr(uw, attr, None)
        if callable(dt):
            dt = dt()
        if dt is not None:
            return float(dt), f"{name}.{attr}"
    timestep = getattr(getattr(getattr(uw, "model", None), "opt", None), "timestep", None)
    for attr in ("frame_skip", "n_substeps"):
        n = getattr(uw, attr, None)
        if timestep is not None and isinstance(n, (int, np.integer)) and n > 0:
            return n * float(timestep), f"{name}.{attr} x model.opt.timestep"
    return None, ""
