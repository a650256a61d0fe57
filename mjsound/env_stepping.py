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
:class:`DmPhysicsStepping`  a dm_control env's ``physics`` (suite, composer,    ``physics.step(nstep)``
                            gym-aloha's ``AlohaEnv._env``)
:class:`MjSimStepping`      robosuite's ``MjSim`` (robosuite 1.5, LIBERO)        ``sim.step()``, ``sim.step2()``
==========================  ==================================================  =====================================

:func:`find_stepping` looks at the unwrapped gymnasium env and, one level down, at its
attributes (an inner env that shares its model: gymnasium-robotics' mazes; a dm_control
environment: gym-aloha; a robosuite env: ``robosuite.wrappers.GymWrapper``).

The hooks run the env's own MuJoCo calls and tell the audio simulator after each completed
step: the fused ``AudioSimulator.stepper()`` where the route is a plain run of ``mj_step``
(gymnasium, gymnasium-robotics, dm_control without legacy stepping), else
``sim.step(render=False)`` after each of the env's own steps, the own-loop route, whose audio
``sim.flush()`` returns once per env step (:meth:`mjsound.env_audio.EnvAudio.end_step`).
"""

from __future__ import annotations

import weakref

import numpy as np

__all__ = ["Stepping", "GymMujocoStepping", "RoboticsStepping", "DmPhysicsStepping", "MjSimStepping",
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
        # (EnvAudio.end_step's flush returns that block)
        step = sim.stepper()
        # (data.ctrl read once: each read of it makes a new view; its memory lives as the MjData)
        ctrl_now, rne_post_constraint = data.ctrl, mujoco.mj_rnePostConstraint

        def _step_mujoco_simulation(ctrl, n_frames):
            ctrl_now[:] = ctrl
            step(n_frames)
            rne_post_constraint(model, data)

        self._set(env, "_step_mujoco_simulation", _step_mujoco_simulation)


class RoboticsStepping(GymMujocoStepping):
    """gymnasium-robotics' ``MujocoRobotEnv``: ``_mujoco_step(action)`` (``mj_step(model, data,
    nstep=n_substeps)``) becomes ``n_substeps`` fused steps."""

    route = "gymnasium-robotics MujocoRobotEnv._mujoco_step"

    def _install(self, sim):
        env = self.owner
        step = sim.stepper()

        def _mujoco_step(action):
            step(env.n_substeps)

        self._set(env, "_mujoco_step", _mujoco_step)


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

        def step(nstep: int = 1) -> None:
            nstep = int(nstep)
            with physics.check_invalid_state():
                if getattr(physics, "legacy_step", False):
                    if model.opt.integrator != rk4:
                        mujoco.mj_step2(model, data)  # completes the step mj_step1 began
                        sim.step(render=False)
                        if nstep > 1:
                            sim.substeps(nstep - 1, render=True)
                    else:
                        sim.substeps(nstep, render=True)
                    mujoco.mj_step1(model, data)
                else:
                    sim.substeps(nstep, render=True)  # (rendered in the same numba call; end_step flushes)

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
    if _is_dm_env(env):
        return DmPhysicsStepping(env)
    if _is_mjsim(getattr(env, "sim", None)) and getattr(env, "control_timestep", None) is not None:
        return MjSimStepping(env)
    return None


def find_stepping(uw) -> Stepping | None:
    """The stepping route of a gymnasium env's unwrapped env (module docstring), or None.

    Looks at ``uw`` itself, then at its attributes: an inner gymnasium env that shares its
    ``model`` and ``data`` (gymnasium-robotics' ``AntMazeEnv.ant_env``), a dm_control
    environment (gym-aloha's ``AlohaEnv._env``), a robosuite env (``GymWrapper.env``).
    """
    route = _route_of(uw)
    if route is not None:
        return route
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
        route = _route_of(value)
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
