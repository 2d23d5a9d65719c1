"""Training (CSV log, checkpoints, resume, bad checkpoints) and the numpy policy export
held to torch's own forward pass."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from asvtwin.rl.config import EnvConfig, PpoConfig
from asvtwin.rl.policy import FORMAT, NumpyPolicy, PolicyFileError

pytest.importorskip("stable_baselines3")

TINY = PpoConfig(n_envs=2, n_steps=128, batch_size=64, n_epochs=1)
ENV = EnvConfig(max_steps=150)


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, object]:
    from asvtwin.rl.train import train

    out = tmp_path_factory.mktemp("run")
    res = train("ppo", steps=512, seed=3, out_dir=out, env_config=ENV, ppo=TINY,
                checkpoint_every=256)
    return out, res


def test_training_writes_log_checkpoints_and_policy(run) -> None:
    from asvtwin.rl.train import CSV_FIELDS

    out, res = run
    assert res.steps == 512
    with open(out / "episodes.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert rows and tuple(rows[0]) == CSV_FIELDS
    assert res.episodes == len(rows) >= 2  # 150-step limit: one per environment in 256 steps
    for r in rows:
        assert int(r["length"]) <= 150
        parts = sum(float(r[k]) for k in ("r_path", "r_colav", "r_psf", "r_exists",
                                          "r_collision"))
        assert parts == pytest.approx(float(r["reward"]), rel=1e-9, abs=1e-9)
        assert r["collision"] in ("True", "False")
    assert (out / "checkpoints" / "step_256.zip").exists()
    meta = json.loads((out / "run.json").read_text())
    assert meta["setup"] == "ppo" and meta["checkpoint_step"] == 512 and meta["finished"]


def test_numpy_policy_equals_torch_forward(run) -> None:
    import stable_baselines3 as sb3

    out, res = run
    model = sb3.PPO.load(out / "checkpoints" / "latest.zip", device="cpu")
    pol = NumpyPolicy.load(res.policy_path)
    assert pol.meta["format"] == FORMAT and pol.obs_dim == 186
    obs = np.random.default_rng(0).uniform(0, 1, (16, 186)).astype(np.float32)
    want, _ = model.predict(obs, deterministic=True)
    np.testing.assert_allclose(pol.act(obs), np.clip(want, -1, 1), atol=1e-5)


def test_resume_continues_and_refuses_foreign_runs(run, tmp_path: Path) -> None:
    import shutil

    from asvtwin.rl.train import CheckpointError, train

    src, _ = run
    out = tmp_path / "r"
    shutil.copytree(src, out)
    res = train("ppo", steps=1024, seed=3, out_dir=out, env_config=ENV, ppo=TINY,
                checkpoint_every=256, resume=True)
    assert res.steps == 1024
    with open(out / "episodes.csv", newline="") as fh:
        steps = [int(r["global_step"]) for r in csv.DictReader(fh)]
    assert steps == sorted(steps) and steps[-1] > 512
    with pytest.raises(CheckpointError, match=r"run.json: setup is 'ppo'.*'ppo_psf'"):
        train("ppo_psf", steps=2048, seed=3, out_dir=out, env_config=ENV, ppo=TINY,
              resume=True)
    with pytest.raises(CheckpointError, match="seed is 3"):
        train("ppo", steps=2048, seed=4, out_dir=out, env_config=ENV, ppo=TINY, resume=True)
    # a filter setting changed since the run was logged: irrelevant without a filter,
    # refused for a filtered setup
    meta = json.loads((out / "run.json").read_text())
    del meta["env"]["psf_solver_circles"]
    (out / "run.json").write_text(json.dumps(meta))
    res = train("ppo", steps=1280, seed=3, out_dir=out, env_config=ENV, ppo=TINY,
                checkpoint_every=256, resume=True)
    assert res.steps == 1280
    logged = (out / "run.json").read_text()
    meta = json.loads(logged)
    meta["setup"] = meta["env"]["setup"] = "ppo_psf"
    del meta["env"]["psf_solver_circles"]
    (out / "run.json").write_text(json.dumps(meta))
    with pytest.raises(CheckpointError, match="env is .*psf_solver_circles"):
        train("ppo_psf", steps=2048, seed=3, out_dir=out,
              env_config=ENV, ppo=TINY, resume=True)
    (out / "run.json").write_text(logged)
    (out / "checkpoints" / "latest.zip").write_bytes(b"PK\x03\x04 not a zip at all")
    with pytest.raises(CheckpointError, match=r"latest.zip: cannot load the checkpoint"):
        train("ppo", steps=2048, seed=3, out_dir=out, env_config=ENV, ppo=TINY, resume=True)


def _write(path: Path, **arrays: object) -> Path:
    np.savez(path, **arrays)
    return path


def test_bad_policy_files_name_the_file_and_the_expectation(tmp_path: Path) -> None:
    meta = np.array(json.dumps({"format": FORMAT, "obs_dim": 4}))
    good = {"W0": np.zeros((3, 4)), "b0": np.zeros(3), "W_out": np.zeros((2, 3)),
                "b_out": np.zeros(2), "meta": meta}
    NumpyPolicy.load(_write(tmp_path / "ok.npz", **good))
    cases = {
        "shape.npz": (dict(good, W_out=np.zeros((2, 5))), r"W_out has shape \(2, 5\).*\(k, 3\)"),
        "nometa.npz": ({k: v for k, v in good.items() if k != "meta"}, "no 'meta' array"),
        "foreign.npz": (dict(good, meta=np.array('{"format": "other/9"}')),
                        "format 'other/9', expected"),
        "outputs.npz": (dict(good, W_out=np.zeros((3, 3)), b_out=np.zeros(3)),
                        "3 outputs, expected 2"),
        "nan.npz": (dict(good, W0=np.full((3, 4), np.nan)), "W0 holds NaN"),
        "pickled.npz": (dict(good, W0=np.array([{"a": 1}], dtype=object)), "not a readable"),
    }
    for name, (arrays, msg) in cases.items():
        path = _write(tmp_path / name, **arrays)
        with pytest.raises(PolicyFileError, match=msg) as info:
            NumpyPolicy.load(path)
        assert name in str(info.value)
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(PolicyFileError, match="junk.npz: not a readable"):
        NumpyPolicy.load(tmp_path / "junk.npz")
