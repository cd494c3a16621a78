import pytest
import torch


def pytest_collection_modifyitems(config, items):
    # the tests marked `long` (several processes, or seconds of training) go first, so that the
    # workers of `make test` (pytest-xdist) take them at the start and end together
    items.sort(key=lambda item: "long" not in item.keywords)
    if torch.cuda.is_available():
        return
    skip = pytest.mark.skip(reason="no CUDA device")
    for item in items:
        if "cuda" in item.keywords:
            item.add_marker(skip)


@pytest.fixture
def gen():
    return torch.Generator().manual_seed(0)


@pytest.fixture(autouse=True)
def _eager_kernels(request, monkeypatch):
    """Tests train with the eager SIREN kernels: compiling costs seconds for every new shape of
    the training pass, and the numbers agree to rounding (tests/test_fields.py). The tests of
    compiling are marked ``compile`` or train in processes of their own (tests/test_resume.py)."""
    if "compile" in request.keywords:
        return
    from ginn.train import callbacks

    monkeypatch.setattr(callbacks.CompileKernels, "on_build", lambda self, trainer: None)


@pytest.fixture
def few_heldout_checks(monkeypatch):
    """In-training checks that judge two held-out codes of Z (the default judges
    ``max(16, 2 N)`` in 2D, a grid evaluation each): for the tests of what the checks do to a
    run (multipliers, resume, logs), not of how well they cover Z (tests/test_feasibility.py)."""
    from ginn.tasks.shape import task

    monkeypatch.setitem(task.HELDOUT_LATENTS, "check", {2: 2, 3: 2})
    monkeypatch.setattr(task, "HELDOUT_PER_SHAPE", 1)
