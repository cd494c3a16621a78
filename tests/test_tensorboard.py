"""``training.log: [jsonl, tensorboard]``: the event files hold what metrics.jsonl holds, at the
same iterations, read back with TensorBoard's own reader; a resumed run logs every iteration once."""

import json

import numpy as np
import pytest

from ginn import runs
from ginn.errors import ConfigError
from ginn.train import tblog

pytest.importorskip("tensorboard")
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator  # noqa: E402

SMALL = ["latents.n_shapes=2", "model.hidden=[16,16]", "sampling.n_domain=256", "sampling.n_outside=128",
         "training.threads=1", "training.log_every=3", "training.feasibility_checks=2",
         "training.log=[jsonl,tensorboard]"]


def _read(run_dir) -> EventAccumulator:
    acc = EventAccumulator(str(run_dir / "tensorboard"), size_guidance={"scalars": 0, "images": 0, "tensors": 0})
    acc.Reload()
    return acc


def _records(run_dir) -> list[dict]:
    return [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines()]


@pytest.mark.long
def test_scalars_images_and_steps_match_metrics_jsonl(tmp_path):
    spec, cfg = runs.resolve("obstacle", "demo", {"training": {"iterations": 12}}, sets=SMALL)
    out = runs.train(spec, cfg, tmp_path / "run", progress=False)
    recs = _records(out.run_dir)
    its = [r for r in recs if "event" not in r]
    checks = [r for r in recs if r.get("event") == "feasibility"]
    assert [r["step"] for r in its] == [0, 3, 6, 9, 11] and [r["step"] for r in checks] == [6, 12]
    acc = _read(out.run_dir)
    tags = acc.Tags()["scalars"]
    for term in ("interface", "eikonal", "design_region", "total"):
        ev = acc.Scalars(f"loss/{term}")
        assert [e.step for e in ev] == [r["step"] + 1 for r in its]  # completed iterations
        np.testing.assert_allclose([e.value for e in ev], [r[term] for r in its], rtol=1e-6)
    np.testing.assert_allclose([e.value for e in acc.Scalars("lr")], [r["lr"] for r in its], rtol=1e-6)
    assert [e.step for e in acc.Scalars("feasibility/feasible")] == [6, 12]
    assert [e.value for e in acc.Scalars("feasibility/feasible")] == [r["feasible"] for r in checks]
    assert "feasibility/worst/interface_cd1" in tags and "diagnostics/boundary_converged" in tags
    np.testing.assert_allclose([e.value for e in acc.Scalars("feasibility/ratio/volume_outside")],
                               [r["ratios"]["volume_outside"] for r in checks], rtol=1e-6)
    pngs = [p for p in out.results if p.suffix == ".png"]
    assert pngs and len(acc.Tags()["images"]) == len(pngs)
    img = acc.Images(acc.Tags()["images"][0])[0]
    assert img.step == 12 and img.width > 100 and img.height > 100


def test_resume_logs_every_iteration_once(tmp_path):
    """A crash after the checkpoint at 5 leaves iterations 5-7 in the event file; the resumed run
    purges them (as metrics.jsonl is cut back) and logs them again, once."""
    sets = [*SMALL, "training.log_every=1", "training.checkpoint_every=5", "training.feasibility_checks=0"]
    spec, cfg = runs.resolve("obstacle", "demo", {"training": {"iterations": 10}}, sets=sets)

    class Kill(Exception):
        pass

    def kill(trainer, step, values):
        if step == 7:
            raise Kill

    with pytest.raises(Kill):
        runs.train(spec, cfg, tmp_path / "run", progress=False, results=False, hooks=[kill])
    runs.resume(tmp_path / "run", progress=False)
    its = [r for r in _records(tmp_path / "run") if "event" not in r]
    ev = _read(tmp_path / "run").Scalars("loss/interface")
    assert [e.step for e in ev] == list(range(1, 11))
    np.testing.assert_allclose([e.value for e in ev], [r["interface"] for r in its], rtol=1e-6)


def test_log_must_keep_jsonl_and_needs_the_package(monkeypatch):
    with pytest.raises(ConfigError, match="training.log"):
        runs.resolve("obstacle", "demo", sets=["training.log=[tensorboard]"])
    spec, cfg = runs.resolve("obstacle", "demo", sets=SMALL)
    monkeypatch.setattr("ginn.train.callbacks.tensorboard_available", lambda: False)
    from ginn.tasks import make_task
    from ginn.train.trainer import Trainer

    with pytest.raises(ConfigError, match=r"training.log: tensorboard needs the tensorboard package"):
        Trainer(make_task(spec, cfg), cfg, None, progress=False)
    assert tblog.tensorboard_available()
