
import pytest


@pytest.fixture
def fake_analyze(monkeypatch):
    """Modal analysis replaced by :func:`mjsound.sim.stub.stub_model` (8 modes from 430 Hz, no FEM);
    returns the list of meshes it was asked for."""
    import mjsound.modal.analyze as an
    from mjsound.sim.stub import stub_model

    calls = []

    def fake(mesh, material, **kw):
        calls.append(mesh)
        return stub_model(mesh, material, 8, 430.0)

    monkeypatch.setattr(an, "analyze", fake)
    return calls


@pytest.fixture(autouse=True)
def _isolated_cache(tmp_path_factory, monkeypatch):
    """Every test gets its own model cache so no test sees another's results."""
    monkeypatch.setenv("MJSOUND_CACHE_DIR", str(tmp_path_factory.mktemp("cache")))
    yield


import os  # noqa: E402

# dm_control renders offscreen through EGL here (gym-aloha's observations are camera images);
# its default, GLFW, needs a display
os.environ.setdefault("MUJOCO_GL", "egl")

# gymnasium-robotics 1.4.2 and dm_control 1.0.50 (the releases pip installs) break on mujoco
# 4.0.0; their envs run in these tests through mjsound.compat's opt-in patches (documented
# there and in the README, "Your own scenes"). Both do nothing where the upstream works.
from mjsound.compat import patch_dm_control, patch_gymnasium_robotics  # noqa: E402

patch_gymnasium_robotics()
patch_dm_control()
