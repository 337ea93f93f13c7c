"""Expert data collection: schema, labels, modes, resumption, determinism, corruption, CLI.

Targets are 0.8-1.0 m away (the default is 2.5-3.5 m) so that each one takes about half a second of
wall time; the whole file runs in well under a minute.
"""

import json
import shutil

import numpy as np
import pytest

from krl.control.expert import RIDE_HEIGHT_RANGE, STEP_HEIGHT_RANGE, ExpertParams, MPCExpert
from krl.data.collect import CollectConfig, collect_dataset
from krl.data.reader import load_dataset
from krl.data.schema import FIELDS, SCHEMA_VERSION, DatasetError
from krl.data.storage import SettingsMismatchError
from krl.robots.a1.constants import FOOT_RADIUS
from krl.util.timing import CONTROL_DT

SHORT = (0.8, 1.0)

TABLE_A1 = {  # Table A.1 variable -> (column, width)
    "v_base": ("base_lin_vel", 3),
    "a_base": ("base_ang_vel", 3),
    "v_cmd": ("v_cmd", 2),
    "a_cmd": ("yaw_cmd", 0),
    "q": ("q", 12),
    "q_dot": ("dq", 12),
    "q_ddot": ("ddq", 12),
    "phi": ("phase", 4),
    "CoM": ("com", 3),
    "p": ("foot_pos", 12),
    "p_ref": ("foot_ref", 12),
    "p_next": ("foot_pos_next", 12),
}


def small_config(**overrides) -> CollectConfig:
    values = {"targets": 4, "targets_per_episode": 2, "target_distance": SHORT}
    values.update(overrides)
    return CollectConfig(**values)


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    """A base collection of 4 targets in 2 episodes, collected without interruption."""
    out = tmp_path_factory.mktemp("small") / "ds"
    summary = collect_dataset(out, small_config())
    return out, summary


def test_every_table_a1_field_with_its_shape(small):
    out, summary = small
    ds = load_dataset(out)
    n = ds.num_rows
    assert n == summary.rows > 500
    assert (ds.num_episodes, ds.num_targets) == (2, 4)
    assert ds.targets_reached + ds.falls + ds.timeouts == 4
    for column, width in TABLE_A1.values():
        values = ds[column]
        assert values.shape == ((n, width) if width else (n,)), column
        assert np.isfinite(values).all(), column
    for spec in FIELDS:
        assert ds[spec.name].shape == (n, *spec.shape)
        assert ds[spec.name].dtype == np.dtype(spec.dtype)
    assert ds.metadata["schema_version"] == SCHEMA_VERSION
    settings = ds.settings
    assert settings["mode"] == "base" and settings["seed"] == 0
    assert settings["expert"]["stance_duration"] == 0.2
    assert settings["expert"]["mpc"]["horizon"] == 10
    assert settings["terrain"]["name"] == "flat"
    assert settings["target_distance"] == list(SHORT)
    assert ds.metadata["created"] and ds.metadata["krl_version"]
    # the Parquet files describe themselves too
    import pyarrow.parquet as pq

    schema = pq.read_schema(out / ds.parts[0]["file"])
    assert schema.metadata[b"krl.schema_version"] == str(SCHEMA_VERSION).encode()
    file_meta = json.loads(schema.metadata[b"krl.dataset"])
    assert file_meta["dataset"]["settings"] == settings
    assert schema.field("foot_pos").metadata[b"frame"] == b"base"


def test_rows_are_consistent_control_steps(small):
    ds = load_dataset(small[0])
    t = ds["time"]
    for episode in range(ds.num_episodes):
        times = t[ds["episode"] == episode]
        np.testing.assert_allclose(np.diff(times), CONTROL_DT)
    # q̈ is the finite difference of q̇ within a segment (next row's q̇ is this row's after-state)
    same = ~ds["new_segment"][1:]
    ddq = (ds["dq"][1:] - ds["dq"][:-1]) / CONTROL_DT
    np.testing.assert_allclose(ds["ddq"][:-1][same], ddq[same], rtol=1e-4, atol=0.5)
    # p' of one row is p of the next
    np.testing.assert_allclose(ds["foot_pos_next"][:-1][same], ds["foot_pos"][1:][same], atol=1e-6)
    # phases: swing <=> normalised phase > 1, sine phase agrees
    assert np.array_equal(~ds["stance"], ds["normalised_phase"] > 1.0)
    np.testing.assert_allclose(ds["sine_phase"], np.sin(np.pi * ds["normalised_phase"]), atol=1e-5)
    # CoM in the base frame is near the trunk origin; projected gravity is a unit vector
    assert np.abs(ds["com"]).max() < 0.1
    np.testing.assert_allclose(np.linalg.norm(ds["projected_gravity"], axis=1), 1.0, atol=1e-5)
    assert (ds["v_cmd"] != 0).any() and (np.abs(ds["v_cmd"]) <= 0.5 + 1e-6).all()


def test_labels_stance_and_swing(small):
    ds = load_dataset(small[0])
    ref = ds["foot_ref"].reshape(-1, 4, 3)
    after = ds["foot_pos_next"].reshape(-1, 4, 3)
    before = ds["foot_pos"].reshape(-1, 4, 3)
    stance = ds["stance"]
    # stance legs: p_ref is the current position, and p' differs by the step's motion (a few mm)
    np.testing.assert_allclose(ref[stance], before[stance], atol=1e-6)
    assert np.abs(ref[stance] - after[stance]).max() < 0.03
    # swing legs: p_ref is a swing target, above the ground the stance feet stand on
    swing = ~stance
    assert swing.any()
    ride = ds["ride_height"][:, None].repeat(4, axis=1)
    ground = -ride[swing] + FOOT_RADIUS  # foot-centre height on flat ground in a level base frame
    assert (ref[swing][:, 2] > ground - 0.03).all()
    assert (ref[swing][:, 2] > ground + 0.02).mean() > 0.5  # most of a swing is in the air
    apex = ground + ds["step_height"][:, None].repeat(4, axis=1)[swing]
    assert (ref[swing][:, 2] <= apex + 1e-3).all()


def test_resume_after_interruption_equals_an_uninterrupted_run(small, tmp_path, monkeypatch):
    reference = load_dataset(small[0])
    out = tmp_path / "ds"

    # 1) killed between episodes: episode 0 is written, episode 1 never starts
    def stop(part):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        collect_dataset(out, small_config(), on_episode=stop)
    assert [p["episode"] for p in json.loads((out / "manifest.json").read_text())["parts"]] == [0]

    # 2) killed in the middle of episode 1: only that episode is lost, nothing half-written remains
    original_act = MPCExpert.act
    calls = {"n": 0}

    def act(self, state, command):
        calls["n"] += 1
        if calls["n"] == 300:
            raise KeyboardInterrupt
        return original_act(self, state, command)

    monkeypatch.setattr(MPCExpert, "act", act)
    manifest_before = (out / "manifest.json").read_bytes()
    part0 = (out / "part-00000.parquet").read_bytes()
    with pytest.raises(KeyboardInterrupt):
        collect_dataset(out, small_config())
    monkeypatch.setattr(MPCExpert, "act", original_act)
    assert (out / "manifest.json").read_bytes() == manifest_before
    assert (out / "part-00000.parquet").read_bytes() == part0
    assert sorted(p.name for p in out.iterdir()) == ["manifest.json", "part-00000.parquet"]

    # 3) resumed: episode 0 is kept, episode 1 collected
    summary = collect_dataset(out, small_config())
    assert (summary.episodes_collected, summary.episodes) == (1, 2)
    assert (out / "part-00000.parquet").read_bytes() == part0
    resumed = load_dataset(out)
    assert resumed.num_rows == reference.num_rows
    for spec in FIELDS:
        np.testing.assert_array_equal(resumed[spec.name], reference[spec.name], err_msg=spec.name)
    assert resumed.content_hash == reference.content_hash
    # no duplicate or missing rows: (episode, time) is unique and complete
    steps = np.round(resumed["time"] / CONTROL_DT).astype(int)
    keys = set(zip(resumed["episode"].tolist(), steps.tolist(), strict=True))
    assert len(keys) == resumed.num_rows

    # 4) running it again collects nothing
    again = collect_dataset(out, small_config())
    assert again.episodes_collected == 0 and again.rows == reference.num_rows


def test_more_targets_extends_the_dataset(small, tmp_path):
    out = tmp_path / "ds"
    shutil.copytree(small[0], out)
    summary = collect_dataset(out, small_config(targets=5))
    assert (summary.episodes_collected, summary.episodes, summary.targets) == (1, 3, 5)
    ds = load_dataset(out)
    assert ds.metadata["targets_requested"] == 5
    assert sorted(set(ds["target_index"].tolist())) == [0, 1, 2, 3, 4]
    # an episode that would need a different number of targets is a clear error
    with pytest.raises(SettingsMismatchError, match="episode 2"):
        collect_dataset(out, small_config(targets=6))


@pytest.mark.parametrize(
    ("overrides", "key"),
    [
        ({"mode": "ext"}, "mode"),
        ({"seed": 1}, "seed"),
        ({"expert": ExpertParams(step_height=0.1)}, "expert.step_height"),
        ({"terrain": "sinusoid"}, "terrain.name"),
        ({"target_distance": (0.9, 1.0)}, "target_distance"),
    ],
)
def test_settings_mismatch_on_resume_is_an_error(small, tmp_path, overrides, key):
    out = tmp_path / "ds"
    shutil.copytree(small[0], out)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    with pytest.raises(SettingsMismatchError, match=key.replace(".", r"\.")):
        collect_dataset(out, small_config(**overrides))
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_corrupt_truncated_or_missing_files(small, tmp_path):
    out = tmp_path / "ds"
    shutil.copytree(small[0], out)
    part = out / "part-00001.parquet"
    data = bytearray(part.read_bytes())
    data[len(data) // 2] ^= 0xFF
    part.write_bytes(bytes(data))
    with pytest.raises(DatasetError, match=r"part-00001\.parquet"):
        load_dataset(out)
    # resuming refuses to touch a corrupt part
    with pytest.raises(DatasetError, match=r"part-00001\.parquet"):
        collect_dataset(out, small_config())
    part.write_bytes(bytes(data[: len(data) // 3]))
    with pytest.raises(DatasetError, match=r"part-00001\.parquet"):
        load_dataset(out)
    part.unlink()
    with pytest.raises(DatasetError, match=r"part-00001\.parquet.*missing"):
        load_dataset(out)
    manifest = out / "manifest.json"
    manifest.write_text(manifest.read_text()[:100])
    with pytest.raises(DatasetError, match=r"manifest\.json"):
        load_dataset(out)
    manifest.unlink()
    with pytest.raises(DatasetError, match=r"manifest\.json"):
        load_dataset(out)


def test_a_lost_part_is_collected_again(small, tmp_path):
    out = tmp_path / "ds"
    shutil.copytree(small[0], out)
    (out / "part-00000.parquet").unlink()
    summary = collect_dataset(out, small_config())
    assert summary.episodes_collected == 1
    assert load_dataset(out).content_hash == load_dataset(small[0]).content_hash


@pytest.mark.parametrize("which", ["one", "both"])
def test_ext_mode_heights_are_constant_per_target_and_in_range(tmp_path, which):
    config = small_config(mode="ext", targets=3, targets_per_episode=3, ext_heights=which)
    ds = load_dataset(collect_dataset(tmp_path / "ext", config).path)
    assert ds.settings["ext_heights"] == which
    nominal = (config.expert.step_height, config.expert.ride_height)
    heights = []
    for target in np.unique(ds["target_index"]):
        rows = ds["target_index"] == target
        step, ride = ds["step_height"][rows], ds["ride_height"][rows]
        assert np.ptp(step) == 0 and np.ptp(ride) == 0
        assert STEP_HEIGHT_RANGE[0] <= step[0] <= STEP_HEIGHT_RANGE[1]
        assert RIDE_HEIGHT_RANGE[0] <= ride[0] <= RIDE_HEIGHT_RANGE[1]
        at_nominal = (step[0] == np.float32(nominal[0])) + (ride[0] == np.float32(nominal[1]))
        assert at_nominal == (1 if which == "one" else 0)
        heights.append((step[0], ride[0]))
    assert len(set(heights)) == 3
    assert ds.num_targets == 3


def test_ext_heights_choice_is_checked():
    with pytest.raises(ValueError, match="ext_heights must be one of one, both"):
        CollectConfig(mode="ext", ext_heights="neither")


def test_dyn2_starts_every_target_standing_at_the_spawn(tmp_path):
    config = small_config(mode="dyn2", targets=3, targets_per_episode=3)
    ds = load_dataset(collect_dataset(tmp_path / "dyn2", config).path)
    spawn = np.array(ds.settings["spawn_xy"])
    starts = np.flatnonzero(np.diff(ds["target_index"], prepend=-1) != 0)
    assert len(starts) == 3
    assert ds["new_segment"][starts].all()
    assert ds["new_segment"].sum() == 3
    np.testing.assert_array_equal(ds["time_since_reset"][starts], 0.0)
    np.testing.assert_allclose(ds["base_pos"][starts, :2], np.broadcast_to(spawn, (3, 2)), atol=1e-9)
    distance = np.linalg.norm(ds["target_xy"][starts] - spawn, axis=1)
    assert ((distance >= SHORT[0] - 1e-9) & (distance <= SHORT[1] + 1e-9)).all()


def test_cli_collect_smoke(tmp_path, capsys):
    from krl.cli import main

    out = tmp_path / "cli"
    argv = ["collect", "--out", str(out), "--targets", "1", "--target-distance", "0.8,0.9", "--json"]
    assert main(argv) == 0
    summary = json.loads(capsys.readouterr().out)
    for key in ("rows", "targets_reached", "falls", "timeouts", "episodes", "sim_seconds", "wall_seconds"):
        assert key in summary
    assert summary["path"] == str(out) and summary["episodes"] == 1 and summary["rows"] > 0
    assert load_dataset(out).settings["expert"]["stance_duration"] == 0.2
    # a settings mismatch is a one-line error with exit status 2
    assert main([*argv, "--mode", "ext"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("krl: error:") and "mode" in err and err.count("\n") == 1
    # a directory that is not a dataset is never written into
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    assert main(["collect", "--out", str(other), "--targets", "1", "--quiet"]) == 2
    assert "not a krl dataset" in capsys.readouterr().err
    assert [p.name for p in other.iterdir()] == ["notes.txt"]


def test_a_fall_is_marked_and_followed_by_a_reset(tmp_path, monkeypatch):

    from krl.sim.batch import SimBatch

    original_step = SimBatch.step
    calls = {"n": 0}

    def step(self, *args, **kwargs):  # the robot reads out fallen after its 150th control step
        states = original_step(self, *args, **kwargs)
        calls["n"] += 1
        if calls["n"] == 150:
            states.fallen[:] = True
        return states

    monkeypatch.setattr(SimBatch, "step", step)
    summary = collect_dataset(tmp_path / "fall", small_config(targets=2, targets_per_episode=2))
    assert (summary.falls, summary.targets_reached, summary.targets) == (1, 1, 2)
    ds = load_dataset(summary.path)
    fell = np.flatnonzero(ds["fell"])
    assert fell.tolist() == [149]
    after = fell[0] + 1
    assert ds["new_segment"][after] and ds["target_index"][after] == 1
    assert ds["time_since_reset"][after] == 0.0 and ds["time"][after] == pytest.approx(150 * CONTROL_DT)
    np.testing.assert_allclose(ds["base_pos"][after, :2], ds.settings["spawn_xy"], atol=1e-9)
    assert json.loads((tmp_path / "fall" / "manifest.json").read_text())["totals"]["falls"] == 1


def test_a_target_not_reached_in_time_is_skipped(tmp_path):
    summary = collect_dataset(
        tmp_path / "slow", small_config(targets=2, targets_per_episode=2, target_time_limit=0.5)
    )
    assert (summary.timeouts, summary.targets_reached, summary.rows) == (2, 0, 200)
    ds = load_dataset(summary.path)
    assert ds["new_segment"].tolist().count(True) == 2 and ds["new_segment"][100]
    assert not ds["fell"].any()


@pytest.mark.slow
def test_full_length_ten_target_collection(tmp_path):
    """The thesis's distances (2.5-3.5 m): the expert reaches every target without a fall."""
    summary = collect_dataset(tmp_path / "full", CollectConfig(targets=10))
    assert (summary.targets_reached, summary.falls, summary.timeouts, summary.unstable) == (10, 0, 0, 0)
    ds = load_dataset(summary.path)
    assert ds.num_rows == summary.rows > 10 * 5.0 / CONTROL_DT  # at least 5 s of walking per target
    steps = np.linalg.norm(
        np.diff(ds["target_xy"][np.r_[0, np.flatnonzero(np.diff(ds["target_index"])) + 1]], axis=0), axis=1
    )
    assert ((steps >= 2.5) & (steps <= 3.5)).all()
    speed = np.linalg.norm(ds["base_lin_vel"][:, :2], axis=1)
    assert speed.max() > 0.3  # it really walks
    for spec in FIELDS:
        if spec.dtype.startswith("float"):
            assert np.isfinite(ds[spec.name]).all(), spec.name
