
import pytest


@pytest.fixture(autouse=True)
def _isolated_cache(tmp_path_factory, monkeypatch):
    """Every test gets its own model cache so no test sees another's results."""
    monkeypatch.setenv("MJSOUND_CACHE_DIR", str(tmp_path_factory.mktemp("cache")))
    yield


# gymnasium-robotics 1.4.2 and dm_control 1.0.50 (the releases pip installs) break on mujoco
# 4.0.0; their envs run in these tests through mjsound.compat's opt-in patches (documented
# there and in the README, "Your own scenes"). Both do nothing where the upstream works.
from mjsound.compat import patch_dm_control, patch_gymnasium_robotics  # noqa: E402

patch_gymnasium_robotics()
patch_dm_control()
