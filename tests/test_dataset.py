"""Demonstrations as a Minari dataset (``pickplace eval --record``, :mod:`pickplace.eval.dataset`): a 20-trial campaign
recorded on two workers loads back with ``minari.load_dataset``, its spaces, lengths and labels are the
environment's, and its episodes replay step for step from their seeds; a failed episode is labelled with its phase,
kind and reason (and replays to the same failure), the drop flag leaves it out, and bad flags name the field."""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
from pathlib import Path

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")
minari = pytest.importorskip("minari")

import pickplace.envs  # noqa: E402, F401  (registers the ids)
from pickplace.cli import main  # noqa: E402
from pickplace.envs.expert import RESET_PHASE, demonstrate, replay  # noqa: E402
from pickplace.errors import ConfigError  # noqa: E402
from pickplace.eval.campaign import CampaignConfig, RandomizationSpec, make_trial, read_results  # noqa: E402
from pickplace.eval.dataset import (  # noqa: E402
    DATASET_ID,
    ENV_ID,
    RecordConfig,
    episode_metadata,
    episode_options,
    load,
    record_campaign,
    replay_episode,
    text,
    write_dataset,
)
from pickplace.task.episode import EpisodeConfig  # noqa: E402
from pickplace.task.phases import MachineConfig  # noqa: E402

#: The phases of a successful demonstration, in order.
PHASES = ["RESET", "EXEC_APPROACH", "DESCEND", "CLOSE", "LIFT", "EXEC_TRANSPORT", "DESCEND_PLACE", "RELEASE"]


def _texts(values: np.ndarray) -> list[str]:
    return [text(v) for v in values]


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    """``pickplace eval --trials 20 --workers 2 --out OUT --record DIR --json``: the campaign's directory and its
    printed summary (with the dataset's figures)."""
    root = tmp_path_factory.mktemp("record")
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["eval", "--trials", "20", "--workers", "2", "--out", str(root / "out"), "--record",
                     str(root / "ds"), "--json"])
    assert code == 0
    return root, json.loads(buf.getvalue())


def test_twenty_episode_campaign_loads_back_with_minari(recorded: tuple[Path, dict],
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """The dataset of the 20-trial campaign, through Minari's own loader: one episode per trial with the trial's
    seed and config, the environment's spaces and spec, N actions within [-1, 1] and N + 1 observations in the
    observation space, the phase labels in the expert's order, the sparse reward at the step that ends a success;
    the expert's success rate is the campaign's (and high on the default randomization)."""
    root, printed = recorded
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(root / "ds"))
    ds = minari.load_dataset(DATASET_ID)
    records = read_results(root / "out" / "results.jsonl")
    assert ds.total_episodes == 20 == len(records)
    assert printed["dataset"]["episodes"] == 20 and printed["dataset"]["steps"] == ds.total_steps
    successes = sum(r.success for r in records)
    assert printed["successes"] == successes >= 18  # the expert on the default randomization (50/50 measured)

    env = ds.recover_environment()
    assert env.spec.id == ENV_ID
    assert env.spec.kwargs == RecordConfig(root / "ds").env_kwargs("ideal")
    assert env.observation_space == ds.observation_space and env.action_space == ds.action_space
    assert ds.action_space.shape == (7,)
    env.close()

    campaign = CampaignConfig(trials=20)
    by_trial = {r.trial: r for r in records}
    for i, ep in enumerate(ds.iterate_episodes()):
        meta = episode_metadata(ds, i)
        trial = int(meta["trial"])
        assert trial == i
        assert int(meta["seed"]) == by_trial[trial].seed == make_trial(campaign, trial).seed
        config = EpisodeConfig.from_dict(json.loads(meta["options"]["config"]))
        assert config == make_trial(campaign, trial).config
        n = len(ep.actions)
        assert n == int(meta["steps"]) and ep.actions.dtype == np.float32
        assert np.all(np.abs(ep.actions) <= 1.0)
        for key, space in ds.observation_space.spaces.items():
            assert ep.observations[key].shape == (n + 1, *space.shape), key
        for k in (0, n // 2, n):
            assert ds.observation_space.contains({key: v[k] for key, v in ep.observations.items()})
        phases = _texts(ep.infos["phase"])
        assert len(phases) == n + 1 and phases[0] == RESET_PHASE
        order = [PHASES.index(p) for p in phases]
        assert order == sorted(order)  # phases in the expert's order, none skipped back
        assert bool(meta["success"]) == by_trial[trial].success
        if meta["success"]:
            assert phases[-1] == "RELEASE" and set(phases) == set(PHASES)
            assert ep.rewards[-1] == 1.0 and not np.any(ep.rewards[:-1]) and ep.terminations[-1]
            assert not np.any(ep.terminations[:-1]) and not np.any(ep.truncations)
            assert ep.infos["place_error_xy_m"][-1] < MachineConfig().place_tolerance_xy_m
            assert _texts(ep.infos["failure_kind"]) == [""] * (n + 1)
        else:
            assert text(meta["failure_kind"]) and (ep.truncations[-1] or ep.terminations[-1])


def test_recorded_episode_replays_to_the_same_outcome(recorded: tuple[Path, dict]) -> None:
    """An episode's actions, replayed in the environment the dataset recovers from the episode's seed and options,
    give the same observations at every step (bit for bit), the same rewards and the same outcome: the episode was
    recorded in a worker process and is replayed in this one. ``pickplace dataset DIR --replay 1`` says so."""
    root, _ = recorded
    ds = load(root / "ds")
    check = replay_episode(ds, 3)
    assert check.steps[0] == check.steps[1] > 50
    assert check.identical_observations and check.max_difference == 0.0
    assert check.same_rewards and check.same_terminations
    assert check.success_stored == check.success_replayed
    assert check.reproduced

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["dataset", str(root / "ds"), "--replay", "1", "--json"])
    data = json.loads(buf.getvalue())
    assert code == 0 and data["episodes"] == 20 and data["replays"][0]["reproduced"]
    assert data["env_kwargs"]["action_mode"] == "joint" and data["control_rate_hz"] == 20.0


def _failing_campaign() -> CampaignConfig:
    """Three trials whose pads' friction is drawn in [0, 0.5] of nominal (nothing else but the poses): with campaign
    seed 5, trial 0 draws 0.025 (the cube slides out of the pads on the lift) and trials 1 and 2 draw 0.45 and 0.37
    (they hold it)."""
    spec = dataclasses.replace(RandomizationSpec(), pad_friction_scale=(0.0, 0.5), object_mass_scale=None)
    campaign = CampaignConfig(randomization=spec, trials=3, seed=5, workers=1)
    drawn = [make_trial(campaign, i).params["pad_friction_scale"] for i in range(3)]
    assert drawn[0] < 0.03 and min(drawn[1:]) > 0.3
    return campaign


def test_failed_episode_is_labelled_replays_and_can_be_dropped(tmp_path: Path) -> None:
    """A trial whose cube slides out of the pads is kept, labelled at its last step and in its metadata with the
    phase (LIFT), kind (GraspFailed) and reason, truncated there by the expert; its replay ends in the same state
    (the cube still on the table, the hand 15 cm up); ``failures="drop"`` writes the same trials without it; a
    resumed campaign keeps the episodes recorded before and rebuilds the dataset."""
    campaign = _failing_campaign()
    record = RecordConfig(tmp_path / "ds")
    done = record_campaign(campaign, tmp_path / "out", record)
    assert done.dataset.episodes == 3 and done.dataset.successes == 2
    ds = load(tmp_path / "ds")
    meta = episode_metadata(ds, 0)
    assert not meta["success"]
    assert (text(meta["failure_phase"]), text(meta["failure_kind"])) == ("LIFT", "GraspFailed")
    assert "rose" in text(meta["failure_reason"])
    ep = ds[0]
    assert _texts(ep.infos["phase"])[-1] == "LIFT"
    assert text(ep.infos["failure_kind"][-1]) == "GraspFailed" and text(ep.infos["failure_phase"][-1]) == "LIFT"
    assert _texts(ep.infos["failure_kind"][:-1]) == [""] * (len(ep.actions))
    assert ep.truncations[-1] and not ep.terminations.any() and not ep.rewards.any()
    assert [bool(episode_metadata(ds, i)["success"]) for i in (1, 2)] == [True, True]

    check = replay_episode(ds, 0)
    assert check.reproduced and check.failure_stored == "GraspFailed in LIFT" and not check.success_replayed
    env = ds.recover_environment()
    obs, *_ = replay(env, int(meta["seed"]), ep.actions, meta["options"])
    env.close()
    lift = _texts(ep.infos["phase"]).index("LIFT")
    assert obs["tcp_pos"][-1, 2] - obs["tcp_pos"][lift - 1, 2] > 0.1  # the hand rose
    assert abs(obs["object_pos"][-1, 0, 2] - obs["object_pos"][0, 0, 2]) < 0.003  # the cube did not

    dropped = write_dataset(tmp_path / "out", RecordConfig(tmp_path / "ds2", failures="drop"), campaign)
    assert (dropped.episodes, dropped.trials, dropped.dropped) == (2, (1, 2), (0,))
    ds2 = load(tmp_path / "ds2")
    assert [int(episode_metadata(ds2, i)["trial"]) for i in range(2)] == [1, 2]
    assert ds2.storage.metadata["pickplace"]["dropped"] == [0]

    # a resumed campaign runs only its new trial and rebuilds the dataset with the episodes recorded before
    with pytest.raises(ConfigError, match="already holds the dataset"):
        record_campaign(campaign, tmp_path / "out2", record)
    before = ds[1].actions.copy()
    more = dataclasses.replace(campaign, trials=4)
    resumed = record_campaign(more, tmp_path / "out", record, resume=True)
    assert resumed.run.trials_run == 1 and resumed.dataset.trials == (0, 1, 2, 3)
    ds3 = load(tmp_path / "ds")
    np.testing.assert_array_equal(ds3[1].actions, before)


def test_failure_before_the_arm_moves_is_one_labelled_step() -> None:
    """An object the pads cannot hold (3 kg at friction 0.4) is refused before anything moves: one step that
    commands nothing (the joints' targets kept, the gripper open), labelled IDLE / CannotHold."""
    env = gym.make(ENV_ID, **RecordConfig(Path("unused")).env_kwargs("ideal"))
    config = EpisodeConfig().with_object(mass_kg=3.0, friction=0.4)
    demo = demonstrate(env, 0, episode_options(config))
    env.close()
    assert demo.steps == 1 and not demo.success
    assert (demo.failure_phase, demo.failure_kind) == ("IDLE", "CannotHold")
    np.testing.assert_array_equal(demo.actions[0], [0, 0, 0, 0, 0, 0, -1])
    assert list(demo.infos["phase"]) == [RESET_PHASE, "IDLE"] and demo.truncations[-1]
    np.testing.assert_array_equal(demo.observations["target_q"][1], demo.observations["target_q"][0])


@pytest.mark.parametrize(("kwargs", "field"), [
    ({"failures": "maybe"}, "record.failures"),
    ({"dataset_id": "expert"}, "record.dataset_id"),
    ({"dataset_id": "pickplace/expert"}, "record.dataset_id"),
    ({"control_rate_hz": 100.0}, "record.control_rate_hz"),
    ({"max_joint_step_rad": 0.5}, "record.max_joint_step_rad"),
])
def test_bad_record_settings_name_the_field(tmp_path: Path, kwargs: dict, field: str) -> None:
    with pytest.raises(ConfigError) as exc:
        RecordConfig(tmp_path, **kwargs)
    assert exc.value.field == field


def test_bad_record_flags(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The CLI refuses bad recording flags before any trial runs, naming them."""
    out, ds = str(tmp_path / "out"), str(tmp_path / "ds")
    assert main(["eval", "--trials", "2", "--out", out, "--record-failures", "drop"]) == 1
    assert "--record-failures goes with --record DIR" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["eval", "--trials", "2", "--out", out, "--record", ds, "--record-failures", "maybe"])
    assert exc.value.code == 2 and "--record-failures: invalid choice: 'maybe'" in capsys.readouterr().err
    assert main(["eval", "--trials", "2", "--out", out, "--record", ds, "--record-rate", "33"]) == 1
    assert "control_rate_hz = 33.0 is invalid" in capsys.readouterr().err
    assert main(["eval", "--trials", "2", "--out", out, "--record", ds, "--task", "stack"]) == 1
    assert "record = " in capsys.readouterr().err
    assert main(["eval", "--trials", "2", "--out", out, "--record", ds, "--profile", "realistic"]) == 1
    assert "profile = 'realistic' is invalid: must be 'ideal' to record" in capsys.readouterr().err
    assert main(["dataset", str(tmp_path / "nothing")]) == 1
    assert "holds no dataset pickplace/expert-v0" in capsys.readouterr().err
    assert not (tmp_path / "out" / "results.jsonl").exists()
