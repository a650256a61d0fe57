"""mjsound.compat's opt-in fixes for Meta-World 3.0.0 and robosuite 1.5.2 on mujoco 4 (issue 36
item 3, issue 40 item 7): the fixed upstream code computes what it meant to, and the envs run
through the audio wrappers."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
import pytest

from mjsound.compat import patch_metaworld, patch_robosuite

patch_metaworld()
patch_robosuite()


def test_metaworld_weld_is_given_not_recomputed():
    import metaworld  # noqa: F401  (registers the envs)

    assert patch_metaworld() == ["metaworld.sawyer_xyz_env.SawyerMocapBase.reset_mocap_welds"]  # idempotent
    env = gym.make("Meta-World/MT1", env_name="reach-v3")
    m, d = env.unwrapped.model, env.unwrapped.data
    (weld,) = np.flatnonzero(m.eq_type == mujoco.mjtEq.mjEQ_WELD)
    want = [0, 0, 0, 0, 0, 0, -1, 0, 0, 0, 5.0] + [0.0] * (mujoco.mjNEQDATA - 11)
    np.testing.assert_array_equal(m.eq_data[weld], want)
    # the 12th number 0: mj_setConst keeps Meta-World's relative pose (1 would recompute it
    # from qpos0, where hand and mocap body do not coincide)
    mujoco.mj_setConst(m, d)
    np.testing.assert_array_equal(m.eq_data[weld], want)
    # the weld holds the hand on the mocap target: the hand follows a commanded move
    env.reset(seed=0)
    start = env.unwrapped.data.mocap_pos[0].copy()
    for i in range(20):  # 5 cm down, then held
        env.step(np.array([0.0, 0.0, -1.0 if i < 5 else 0.0, 0.0]))
    mocap = env.unwrapped.data.mocap_pos[0]
    hand = env.unwrapped.data.body("hand").xpos
    assert mocap[2] < start[2] - 0.04  # the target went down...
    assert np.linalg.norm(hand - mocap) < 0.005  # ... and the hand with it
    env.close()


def test_metaworld_task_is_heard():
    import metaworld  # noqa: F401

    from mjsound.wrappers import AudioObservation

    env = AudioObservation(gym.make("Meta-World/MT1", env_name="pick-place-v3"), sample_rate=16000,
                           default_material=None, materials={"tablelink": "wood", "leftpad_geom": "steel"},
                           progress=False)
    u = env.unwrapped
    assert env.window == round(u.dt * 16000) == 200
    env.reset(seed=0)
    peaks, samples = [], 0
    for i in range(40):  # the gripper driven down onto the table
        obs, _, _, _, info = env.step(np.array([0.0, 0.0, -1.0, 1.0]))
        assert env.observation_space["audio"].contains(obs["audio"])  # (Meta-World's own leaves its space)
        peaks.append(info["audio_peak_pa"])
        samples += info["audio_samples"]
    assert env.sim.steps == 40 * u.frame_skip  # every substep heard
    assert samples == 40 * 200
    assert max(peaks) > 0
    env.close()


def test_robosuite_joint_addresses_and_mass_matrix():
    import robosuite
    from robosuite.controllers.parts import controller

    assert len(patch_robosuite()) == 3  # idempotent
    env = robosuite.make("Lift", robots="Panda", has_renderer=False, has_offscreen_renderer=False,
                         use_camera_obs=False, hard_reset=False)
    env.reset()
    sim = env.sim
    m, d = sim.model._model, sim.data._data
    # joint addresses (binding_utils asserted on mujoco 4's enums): a hinge's is one address,
    # the cube's free joint a (start, start + 7) range
    j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "robot0_joint1")
    assert sim.model.get_joint_qpos_addr("robot0_joint1") == m.jnt_qposadr[j]
    cube = [n for n in (m.joint(i).name for i in range(m.njnt)) if n.startswith("cube")][0]
    a = m.jnt_qposadr[m.joint(cube).id]
    assert sim.model.get_joint_qpos_addr(cube) == (a, a + 7)
    # the controller's mass matrix is MuJoCo's dense inertia at the step's state
    env.step(np.zeros(env.action_dim))
    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, full)
    ctrl = env.robots[0].part_controllers["right"]
    qv = ctrl.qvel_index
    np.testing.assert_allclose(ctrl.mass_matrix, full[np.ix_(qv, qv)], rtol=1e-12, atol=0)
    assert controller.mujoco.mj_fullM is not mujoco.mj_fullM
    env.close()
