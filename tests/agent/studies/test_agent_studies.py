"""Agent studies on Optuna: the designs against the thesis's tables, and the runner's promises (every
planned entry trained once, interrupted and stale trials resumed, finished ones never redone) on a fake
training whose learning curve is known; one real tiny study end to end."""

from __future__ import annotations

import json
import time
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import optuna
import pytest
from agent_fakes import LOG_COLUMNS, TINY_STUDY

from krl.agent.config import AgentConfig, ResidualConfig
from krl.agent.studies import designs, runner
from krl.agent.studies.designs import STUDIES, StudyDesign, Variant
from krl.agent.studies.report import replay_pruning, replay_resampled, write_study_report
from krl.agent.studies.runner import CONFIRM, LIST, SEARCH, StudySettings, open_stage, work
from krl.cli import main
from krl.task.reward import reward_name

COLUMNS = LOG_COLUMNS


def fake_train(calls: list):
    """A stand-in for :func:`krl.agent.train.train`: logs 4 rollouts whose targets reached rise to
    ``10 * learning_rate * 1000 / 10`` (so the learning rate decides a search), honours an SB3 callback's
    stop at ``_on_step``, and records each call."""

    def train(folder, config, seed, progress, log, workers, num_envs, callbacks):
        calls.append((Path(folder).name, seed))
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        goal = config.ppo.learning_rate * 1000 + (0.1 if seed == 2 else 0.0)
        rows, steps = [], 0
        for rollout in range(1, 5):
            steps = rollout * config.total_steps // 4
            targets = goal * rollout / 4
            rows.append([steps, 1.0, targets, 0.0, min(1.0, targets / 5)])
            stop = False
            for callback in callbacks:
                callback.num_timesteps = steps
                callback.model = SimpleNamespace(
                    logger=SimpleNamespace(name_to_value={"episode/targets_reached": targets})
                )
                callback._on_rollout_end()
                stop = stop or not callback._on_step()
            if stop:
                break
        lines = [",".join(COLUMNS)] + [",".join(map(str, row)) for row in rows]
        (folder / "progress.csv").write_text("\n".join(lines) + "\n")
        return {"env_steps": steps, "wall_seconds": 1.0, "out": str(folder), "policy": ""}

    return train


@pytest.fixture
def calls(monkeypatch):
    made: list = []
    monkeypatch.setattr("krl.agent.train.train", fake_train(made))
    return made


LIST_DESIGN = StudyDesign(
    name="tiny-list",
    title="test",
    base={},
    budget=400,
    variants=(
        Variant("slow", "lr 1e-3", {"ppo": {"learning_rate": 1e-3}}),
        Variant("fast", "lr 3e-3", {"ppo": {"learning_rate": 3e-3}}),
    ),
    seeds=(1, 2),
)


def search_space(trial):
    return {"ppo": {"learning_rate": trial.suggest_categorical("learning_rate", [5e-5, 5e-4, 1e-3, 3e-3])}}


SEARCH_DESIGN = StudyDesign(
    name="tiny-search",
    title="test",
    base={},
    budget=400,
    space=search_space,
    trials=6,
    top=2,
    confirm_budget=200,
    seeds=(1, 2),
)


def sqlite(tmp_path: Path) -> str:
    return f"sqlite:///{tmp_path / 'study.db'}"


def test_the_ppo_search_space_is_table_a3():
    ppo = STUDIES["ppo-search"]
    assert (ppo.budget, ppo.trials, ppo.top, ppo.confirm_budget) == (3_000_000, 100, 5, 5_000_000)
    assert designs.PPO_LEARNING_RATES == (3e-3, 1e-3, 5e-4, 5e-5)
    assert (designs.PPO_EPOCHS, designs.PPO_BATCH_SIZES) == ((5, 10, 20), (500, 2000, 4000))
    assert designs.PPO_NETWORKS == {"large": [256, 256, 256], "medium": [256, 256], "small": [128, 128]}
    assert designs.PPO_ENTROPY_RANGE == (1e-6, 1e-3) and ppo.base["ppo"]["rollout_steps"] == 20_000
    trial3 = {"learning_rate": 1e-3, "ent_coef": 5e-6, "network": "small", "n_epochs": 10, "batch_size": 4000}
    drawn = designs.ppo_space(optuna.trial.FixedTrial(trial3))["ppo"]
    assert drawn == {
        "learning_rate": 1e-3,
        "ent_coef": 5e-6,
        "shared": [128, 128],
        "n_epochs": 10,
        "batch_size": 4000,
    }
    config = runner.trial_config(ppo, StudySettings.of(ppo), {"ppo": drawn}, 3_000_000)
    assert config.env.heightfield_max_height == (0.02, 0.02) and not config.env.pushes  # heightfield_mild
    assert config.env.heightfield_probability == 1.0 and reward_name(config.env.reward) == "initial"
    assert config.observation.features[-2:] == ("phase", "foot_contact") and config.ppo.actor == (128,)


def test_the_state_space_sets_are_fig_4_20():
    study = STUDIES["state-space"]
    sets = {
        v.name: v.overrides["observation"]["features"][len(designs.CORE_FEATURES) :] for v in study.variants
    }
    assert sets["residual-contacts"] == ["residual", "foot_contact"]
    assert sets["targets-contacts"] == ["kernel_targets", "foot_contact"] and sets["core"] == []
    assert all(
        v.overrides["observation"]["features"][:7] == list(designs.CORE_FEATURES) for v in study.variants
    )
    config = runner.trial_config(study, StudySettings.of(study), study.variants[-1].overrides, 1)
    assert reward_name(config.env.reward) == "base" and config.num_envs == designs.STUDY_NUM_ENVS


def test_a_list_study_trains_each_entry_once_and_a_rerun_trains_nothing(tmp_path, calls):
    settings = StudySettings.of(LIST_DESIGN)
    work(LIST_DESIGN, settings, tmp_path, sqlite(tmp_path), heartbeat=1, log=lambda _: None)
    assert sorted(calls) == [("fast-seed1", 1), ("fast-seed2", 2), ("slow-seed1", 1), ("slow-seed2", 2)]
    work(LIST_DESIGN, settings, tmp_path, sqlite(tmp_path), heartbeat=1, log=lambda _: None)
    assert len(calls) == 4
    written = write_study_report(LIST_DESIGN, settings, sqlite(tmp_path), tmp_path / "report")
    table = (tmp_path / "report" / "tiny-list.md").read_text()
    assert "| fast | 2 (1,2) | 3.05 ± 0.07 |" in table  # final = mean of the last 20 % of rollouts: 3 and 3.1
    assert written["status"][LIST] == {"finished": 4, "pruned": 0, "failed": 0, "missing": 0}
    with pytest.raises(runner.StudyError, match="other settings \\(budget: budget 400\\)"):
        work(LIST_DESIGN, StudySettings.of(LIST_DESIGN, budget=800), tmp_path, sqlite(tmp_path))


def test_a_popped_entry_that_another_process_holds_is_surplus_not_a_second_run(tmp_path, calls):
    settings = StudySettings.of(LIST_DESIGN)
    study = open_stage(LIST_DESIGN, settings, LIST, sqlite(tmp_path))
    entries = runner.plan_entries(LIST_DESIGN, settings, LIST)
    runner.enqueue(study, entries)
    distributions = {
        "variant": optuna.distributions.CategoricalDistribution(["slow", "fast"]),
        "seed": optuna.distributions.CategoricalDistribution([1, 2]),
    }
    for entry in entries[:2]:  # the race: another process enqueued these twice
        twice = optuna.trial.create_trial(
            state=optuna.trial.TrialState.WAITING,
            user_attrs={"key": entry["key"]},
            params=entry["params"],
            distributions=distributions,
        )
        study.add_trial(twice)
    work(LIST_DESIGN, settings, tmp_path, sqlite(tmp_path), heartbeat=1, log=lambda _: None)
    assert len(calls) == 4 and len({call for call in calls}) == 4
    surplus = [t for t in study.get_trials() if t.user_attrs.get("surplus")]
    assert len(surplus) == 2 and all(t.state == optuna.trial.TrialState.FAIL for t in surplus)


def test_a_stale_trial_of_a_dead_process_is_retried_in_its_folder(tmp_path, calls):
    settings = StudySettings.of(LIST_DESIGN, seeds=(1,))
    url = sqlite(tmp_path)
    study = open_stage(LIST_DESIGN, settings, LIST, url, heartbeat=1)
    runner.enqueue(study, runner.plan_entries(LIST_DESIGN, settings, LIST))
    dead = study.ask()  # popped by a process that then died: one heartbeat, then silence
    dead.suggest_categorical("variant", ["slow", "fast"]), dead.suggest_categorical("seed", [1])
    study._storage.record_heartbeat(dead._trial_id)
    time.sleep(3.5)
    work(LIST_DESIGN, settings, tmp_path, url, heartbeat=1, log=lambda _: None)
    assert sorted(calls) == [("fast-seed1", 1), ("slow-seed1", 1)]
    states = [t.state.name for t in open_stage(LIST_DESIGN, settings, LIST, url).get_trials()]
    assert states.count("COMPLETE") == 2 and states.count("FAIL") == 1


def test_an_interrupted_trial_is_queued_again_not_lost(tmp_path, monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr("krl.agent.train.train", interrupted)
    settings = StudySettings.of(LIST_DESIGN, seeds=(1,))
    with pytest.raises(KeyboardInterrupt):
        work(LIST_DESIGN, settings, tmp_path, sqlite(tmp_path), log=lambda _: None)
    made: list = []
    monkeypatch.setattr("krl.agent.train.train", fake_train(made))
    work(LIST_DESIGN, settings, tmp_path, sqlite(tmp_path), log=lambda _: None)
    assert sorted(made) == [("fast-seed1", 1), ("slow-seed1", 1)]


@pytest.mark.parametrize("moment", ["is_surplus", "krl.agent.train.train"])
def test_a_trial_interrupted_before_or_in_its_training_is_queued_again(tmp_path, monkeypatch, moment):
    """Ctrl-C or SIGTERM while the popped trial is still being set up (checked against the others, the
    training's imports) loses its entry no more than one inside the training."""

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    target = moment if "." in moment else f"krl.agent.studies.runner.{moment}"
    with monkeypatch.context() as patch:
        patch.setattr(target, interrupted)
        with pytest.raises(KeyboardInterrupt):
            work(LIST_DESIGN, StudySettings.of(LIST_DESIGN, seeds=(1,)), tmp_path, sqlite(tmp_path))
    made: list = []
    monkeypatch.setattr("krl.agent.train.train", fake_train(made))
    settings = StudySettings.of(LIST_DESIGN, seeds=(1,))
    work(LIST_DESIGN, settings, tmp_path, sqlite(tmp_path), log=lambda _: None)
    assert sorted(made) == [("fast-seed1", 1), ("slow-seed1", 1)]


def test_a_search_draws_its_trials_then_confirms_the_best_from_every_seed(tmp_path, calls):
    settings = StudySettings.of(SEARCH_DESIGN, pruner="none")
    work(SEARCH_DESIGN, settings, tmp_path, sqlite(tmp_path), heartbeat=1, log=lambda _: None)
    search = [name for name, _ in calls if "seed" not in name]
    confirm = sorted(call for call in calls if "seed" in call[0])
    assert len(search) == 6 and len(confirm) == 4
    study = open_stage(SEARCH_DESIGN, settings, SEARCH, sqlite(tmp_path))
    best = runner.best_trials(study, 2)
    assert best[0].params["learning_rate"] == max(t.params["learning_rate"] for t in study.trials)
    assert {name.split("-")[0] for name, _ in confirm} == {f"trial{t.number}" for t in best}
    written = write_study_report(SEARCH_DESIGN, settings, sqlite(tmp_path), tmp_path / "report")
    assert written["status"][CONFIRM]["missing"] == 0
    report = (tmp_path / "report" / "tiny-search.md").read_text()
    assert "Pruning replayed on these unpruned trials" in report
    assert "| median (" in report and "| halving (" in report


def curve_trials(finals):
    """Finished trials numbered 0, 1, ... whose targets grow linearly to ``finals`` over 400 env steps."""
    trials = []
    for number, final in enumerate(finals):
        curve = [[step, final * step / 400, 0.0] for step in (100, 200, 300, 400)]
        trials.append(optuna.trial.create_trial(value=final, user_attrs={"curve": curve, "env_steps": 400,
                      "targets_reached": final}, params={}, distributions={}))  # fmt: skip
        trials[-1].number = number
    return trials


def test_the_pruning_replay_counts_the_steps_a_pruner_saves():
    trials = curve_trials([3.0, 3.0, 3.0, 1.0, 2.9])
    replay = replay_pruning(trials, optuna.pruners.MedianPruner(n_startup_trials=3, n_warmup_steps=150))
    assert replay["env_steps_unpruned"] == 2000
    assert replay["env_steps_pruned"] == 1200 + 200 + 200 and replay["kept"] == [0, 1, 2]


def test_a_resampled_replay_draws_a_larger_search_from_the_curves():
    def median():
        return optuna.pruners.MedianPruner(n_startup_trials=3, n_warmup_steps=150)

    good_and_bad = curve_trials([3.0, 1.0])
    drawn = replay_resampled(good_and_bad, median, size=50, top=[0], repeats=5)
    assert drawn == replay_resampled(good_and_bad, median, size=50, top=[0], repeats=5)  # seeded draws
    assert drawn["best_kept"] == 1.0  # the good curve is never below a median
    # a bad copy stops at 200 of 400 steps when most earlier trials were good (else the median is its own
    # curve), the good ones run out: between 1x and 2x
    assert len(drawn["savings"]) == 5 and all(1 <= saving < 2 for saving in drawn["savings"])
    assert max(drawn["savings"]) > 1
    same = replay_resampled(curve_trials([2.0, 2.0]), median, size=20, top=[0], repeats=3)
    assert same["savings"] == [1.0, 1.0, 1.0]  # equal curves: nothing is below the median


def test_krl_agent_study_refuses_bad_input_in_one_line(tmp_path, capsys):
    for argv, message in (
        (["nope"], "unknown study 'nope'; known: ppo-search"),
        (["ppo-search", "--seeds", "1,1"], "seeds must be distinct"),
        (["ppo-search", "--budget", "0"], "at least 1 env step"),
        (["state-space", "--config", str(tmp_path / "none.json")], "--config"),
    ):
        assert main(["agent", "study", *argv, "--out", str(tmp_path / "s")]) == 2
        error = capsys.readouterr().err
        assert message in error and error.count("\n") == 1
    assert not (tmp_path / "s").exists()


def test_a_tiny_study_trains_for_real(tmp_path, capsys):
    tiny = tmp_path / "tiny.json"
    tiny.write_text(json.dumps(TINY_STUDY))
    argv = ["agent", "study", "ppo-search", "--out", str(tmp_path / "s"), "--trials", "1", "--top", "1"]
    argv += ["--seeds", "7", "--budget", "256", "--confirm-budget", "256", "--config", str(tiny)]
    argv += ["--workers", "1", "--jobs", "1", "--quiet", "--json"]
    assert main(argv) == 0
    status = json.loads(capsys.readouterr().out)
    assert status[SEARCH]["finished"] == 1 and status[CONFIRM] == {
        "finished": 1,
        "pruned": 0,
        "failed": 0,
        "missing": 0,
    }
    assert (
        tmp_path / "s" / "trials" / "confirm" / f"trial{status['best'][0]['trial']}-seed7" / "policy.npz"
    ).is_file()
    # --report alone reads the settings the study started with; other settings are still refused
    assert main(["agent", "study", "ppo-search", "--out", str(tmp_path / "s"), "--report", "--json"]) == 0
    json.loads(capsys.readouterr().out)
    report = (tmp_path / "s" / "report" / "ppo-search.md").read_text()
    assert "Budget: 256 env steps per trial, seeds 7; 1 trials, best 1 confirmed for 256" in report
    assert (
        main(["agent", "study", "ppo-search", "--out", str(tmp_path / "s"), "--report", "--budget", "9"]) == 2
    )
    assert "started with other settings" in capsys.readouterr().err
    design = STUDIES["ppo-search"]
    assert runner.stored_settings(design, sqlite(tmp_path)) is None and not (tmp_path / "study.db").exists()
    assert main(["agent", "study", "state-space", "--out", str(tmp_path / "none"), "--report"]) == 2
    error = capsys.readouterr().err
    assert "study state-space has not been started in sqlite:///" in error and error.count("\n") == 1
    assert not (tmp_path / "none").exists()


def test_the_alternative_study_gives_the_kernel_commands_and_measures_zero_commands(tmp_path, capsys):
    study = STUDIES["alternative"]
    commands = runner.trial_config(study, StudySettings.of(study), study.variants[1].overrides, 1)
    assert commands.residual.action_size == 3 and not commands.residual.residuals
    assert "kernel_command" in commands.observation.features
    residual = runner.trial_config(study, StudySettings.of(study), study.variants[0].overrides, 1)
    assert residual.residual.action_size == 12 and residual.observation.features[-2:] == (
        "residual",
        "foot_contact",
    )
    tiny = tmp_path / "tiny.json"
    tiny.write_text(json.dumps(TINY_STUDY))
    argv = ["agent", "study", "alternative", "--out", str(tmp_path / "s"), "--seeds", "7"]
    argv += ["--budget", "256", "--config", str(tiny), "--workers", "1", "--jobs", "1", "--quiet", "--json"]
    assert main(argv) == 0
    assert json.loads(capsys.readouterr().out)[LIST]["finished"] == 2
    assert main([*argv, "--report"]) == 0
    report = (tmp_path / "s" / "report" / "alternative.md").read_text()
    assert "| zero | gives the kernel zero commands" in report and "Runs finished: 2" in report
    rows = (tmp_path / "s" / "report" / "alternative-fixed.csv").read_text().splitlines()
    assert [row.split(",")[0] for row in rows[1:]] == ["follow", "half", "zero"]


def test_a_study_whose_trials_fail_exits_non_zero_naming_the_first_error(tmp_path, capsys):
    tiny = tmp_path / "tiny.json"
    tiny.write_text(json.dumps({**TINY_STUDY, "env": {"episode_time": 60.0}}))  # no episode ends
    argv = ["agent", "study", "alternative", "--out", str(tmp_path / "s"), "--seeds", "7"]
    argv += ["--budget", "256", "--config", str(tiny), "--workers", "1", "--jobs", "1", "--quiet", "--json"]
    assert main(argv) == 1
    captured = capsys.readouterr()
    assert json.loads(captured.out)[LIST]["failed"] == 2  # the status is still printed
    err = captured.err.strip()
    assert err.startswith("krl: 2 trial(s) of study alternative failed, first residual-seed7: StudyError:")
    assert "logged no rollout with an ended episode" in err and len(err.splitlines()) == 1


def test_the_ground_study_is_agent_gaits_recipe_on_other_ground():
    study = STUDIES["gait-ground"]
    settings = StudySettings.of(study)
    configs = {
        v.name: runner.trial_config(study, settings, v.overrides, study.budget) for v in study.variants
    }
    chosen = Path(__file__).parents[3] / "docs/results/agent/gait-heldout/chosen-config.json"
    agent_gait = AgentConfig.load(chosen)  # the held-out choice's recipe, which agent-gait's seeds train
    agent_gait = replace(agent_gait, workers=None)  # a trial takes the machine's (its run records 2)
    on_pyramids = replace(agent_gait.env, heightfield_probability=0.5, pyramids_probability=0.25)
    assert configs["pyramids"] == replace(agent_gait, env=on_pyramids)
    pushed = replace(on_pyramids, push_magnitude=(100.0, 600.0))
    assert configs["pyramids-pushes"] == replace(agent_gait, env=pushed)


def test_the_gait_ablation_adds_one_drive_at_a_time_to_the_final_agent():
    study = STUDIES["gait-ablation"]
    configs = {
        v.name: runner.trial_config(study, StudySettings.of(study), v.overrides, study.budget)
        for v in study.variants
    }
    sizes = {name: config.residual.action_size for name, config in configs.items()}
    assert sizes == {"residual-ext": 12, "heights": 14, "rhythm": 13, "both": 15, "steer-both": 18}
    assert configs["steer-both"].residual.drive_steer and configs["both"].residual.gait_alpha == 0.5
    assert configs["residual-ext"].residual.gait_alpha == ResidualConfig().gait_alpha  # nothing to filter
    assert all(c.residual.kernel == "ext" and c.env.pushes for c in configs.values())
    assert all(c.env.friction == (0.4, 1.0) for c in configs.values())
    assert reward_name(configs["both"].env.reward) == "rp" and configs["both"].num_envs == 16
    assert configs["both"].observation.features[-2:] == ("heights", "clock_rate")
    assert configs["residual-ext"].observation.features == (
        *designs.CORE_FEATURES,
        "residual",
        "foot_contact",
    )
    own = StudySettings.of(study, shared={"residual": {"kernel": "runs/kernel-ext/kernel.npz"}})
    for variant in study.variants:  # krl reproduce's own kernel-ext, in place of the shipped one
        config = runner.trial_config(study, own, variant.overrides, study.budget)
        assert config.residual.kernel == "runs/kernel-ext/kernel.npz"
        assert config.residual.action_size == sizes[variant.name]


def test_the_reward_features_are_table_4_7():
    rewards = {name: reward for name, (_, reward) in designs.TRIAL_REWARDS.items()}
    assert list(rewards) == [
        "initial", "t1-no-com", "t2-no-target", "t3-constraints", "t4-shortfall", "t5-fall", "t6-target",
        "t7-both", "t8-slip-reward", "t9-slip-penalty", "t10-drift-penalty",
    ]  # fmt: skip
    names = {name: [t.name for t in reward.terms] for name, reward in rewards.items()}
    initial = ["linear_velocity", "angular_velocity", "gravity", "target_distance"]
    assert names["initial"] == initial and all(t.weight == 0.01 for t in rewards["initial"].terms)
    assert names["t1-no-com"] == ["linear_velocity", "angular_velocity", "target_distance"]
    assert names["t2-no-target"] == initial[:3]
    assert names["t3-constraints"] == [*initial, "vertical_velocity", "roll_pitch_rate"]
    shortfall = {t.name: t.shortfall for t in rewards["t4-shortfall"].terms}
    assert shortfall == {
        "linear_velocity": True,
        "angular_velocity": True,
        "gravity": False,
        "target_distance": False,
    }
    nominal = {name: (r.fall_penalty, r.target_bonus) for name, r in rewards.items()}
    assert nominal["initial"] == nominal["t4-shortfall"] == (None, None)
    assert (nominal["t5-fall"], nominal["t6-target"], nominal["t7-both"]) == (
        (-5.0, None),
        (None, 5.0),
        (-5.0, 5.0),
    )
    extra = {
        name: rewards[name].terms[-1] for name in ("t8-slip-reward", "t9-slip-penalty", "t10-drift-penalty")
    }
    assert [(t.quantity, t.penalty) for t in extra.values()] == [
        ("stance_slip", False), ("stance_slip", True), ("stance_drift", True),
    ]  # fmt: skip
    assert all(nominal[name] == (-5.0, 5.0) for name in extra)


def test_the_reward_searches_start_from_trial_7():
    for name, key in (("reward-rbf", "q_"), ("reward-weights", "w_")):
        design = STUDIES[name]
        drawn = design.space(optuna.trial.FixedTrial({f"{key}{term}": 3.0 if key == "q_" else 0.002
                                                      for term in designs.RBF_RANGES}))  # fmt: skip
        reward = runner.trial_config(design, StudySettings.of(design), drawn, 1).env.reward
        assert (reward.fall_penalty, reward.target_bonus) == (-5.0, 5.0)
        value = {t.name: (t.steepness if key == "q_" else t.weight) for t in reward.terms}
        assert value == dict.fromkeys(designs.RBF_RANGES, 3.0 if key == "q_" else 0.002)
    assert designs.RBF_RANGES["linear_velocity"] == (15.0, 20.0) and designs.WEIGHT_RANGE == (0.001, 0.005)


def test_a_reward_of_stance_terms_trains_in_the_environment(small_config):
    from dataclasses import replace

    import numpy as np

    from krl.agent.env import ResidualVecEnv

    reward = designs.TRIAL_REWARDS["t10-drift-penalty"][1]
    config = replace(small_config, env=replace(small_config.env, reward=reward, pushes=False))
    env = ResidualVecEnv(config, 2, seed=0)
    env.reset()
    for _ in range(3):
        env.step(np.zeros((2, 12)))
    terms = env.batch.last_terms
    assert set(terms) == {*(t.name for t in reward.terms), "fall", "target_reached"}
    assert np.all(terms["stance_drift"] <= 0.0)
