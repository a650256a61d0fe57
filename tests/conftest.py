
import pytest


@pytest.fixture(autouse=True)
def _isolated_cache(tmp_path_factory, monkeypatch):
    """Every test gets its own model cache so no test sees another's results."""
    monkeypatch.setenv("MJSOUND_CACHE_DIR", str(tmp_path_factory.mktemp("cache")))
    yield
