"""The one episode record: what every driver of the episode loop keeps of an episode."""

import numpy as np

from krl.control.commands import CommandParams
from krl.robots.a1.constants import STANDING_JOINT_ANGLES
from krl.sim.backend import make_backend
from krl.sim.model import build_model
from krl.sim.pushes import OnePush, Push
from krl.task.episode import EpisodeBatch
from krl.task.record import PUSH_VERDICT_TIME, EpisodeRecords
from krl.task.reward import EVALUATION_REWARD
from krl.task.waypoints import TaskStatus, WaypointTask
from krl.util.timing import CONTROL_DT


def _stand(pushes: list[Push | None], steps: int):
    """Two robots standing while their task (a waypoint 5 m ahead) gives them ``steps`` control steps, with
    ``pushes``; the steps, the records, the push verdicts of each step and the tasks."""
    sims = make_backend([build_model("flat")] * 2)
    episodes = EpisodeBatch(sims, EVALUATION_REWARD)
    tasks = [WaypointTask(np.array([[5.0, 0.0]]), CommandParams(), None, steps * CONTROL_DT) for _ in pushes]
    for index, task in enumerate(tasks):
        task.reset(sims.states.base_pos[index, :2])
    episodes.start([0, 1], tasks, [None if push is None else OnePush(push) for push in pushes])
    records = EpisodeRecords(2)
    records.begin([0, 1], pushes)
    taken, verdicts = [], []
    q = np.tile(STANDING_JOINT_ANGLES, (2, 1))
    while episodes.active.any():
        rows = np.flatnonzero(episodes.active)
        step = episodes.step(q)
        records.add(step, rows, sims.step_counts)
        verdicts.append(records.judge_pushes(step))
        taken.append(step)
    return taken, records, verdicts, tasks


def test_a_record_sums_its_robots_steps_and_keeps_the_heading_at_its_push():
    push = Push(10 * CONTROL_DT, np.array([5.0, 0.0, 0.0]), np.zeros(3))
    steps, records, _, tasks = _stand([None, push], 30)
    pushed = records.finish(1, tasks[1].reached_count, tasks[1].status is TaskStatus.TIMED_OUT)
    assert pushed.steps == len(steps) == 30 and pushed.ended == "timed_out" and not pushed.fell
    assert pushed.push_heading == float(steps[10].before.rpy[1, 2])  # before the push's first step
    assert records.finish(0, 0, True).push_heading is None  # no push
    sums = {name: sum(float(step.terms[name][1]) for step in steps) for name in steps[0].terms}
    assert pushed.terms == sums and np.isfinite(list(sums.values())).all()
    rewards = [float(np.sum(list(step.terms.values()), axis=0)[1]) for step in steps]
    assert pushed.reward == sum(rewards)
    moved = [np.hypot(*(s.states.base_pos[1, :2] - s.before.base_pos[1, :2])) for s in steps]
    assert np.isclose(pushed.distance_walked, sum(moved))


def test_a_record_says_what_ended_its_episode():
    records = EpisodeRecords(1)
    records.begin([0])
    out_of_time = records.finish(0, 2, True)
    assert (out_of_time.ended, out_of_time.targets_reached, out_of_time.timed_out) == ("timed_out", 2, True)
    failed = records.finish(0, 2, True, error="MPCError: infeasible")
    # an error ends the walk: the task's waypoints and time do not count, only what the steps reached
    assert (failed.ended, failed.targets_reached, failed.timed_out) == ("error", 0, False)
    assert records.finish(0, 1, False).ended == "finished"


def test_a_push_is_survived_after_the_verdict_time_and_failed_by_a_fall_before_it():
    gentle = Push(0.02, np.array([5.0, 0.0, 0.0]), np.zeros(3))
    topple = Push(0.02, np.array([0.0, 900.0, 100.0]), np.zeros(3), duration=0.2, mode="continuous")
    steps = round(PUSH_VERDICT_TIME / CONTROL_DT) + 10
    taken, records, verdicts, _ = _stand([gentle, topple], steps)
    fall_step = next(k for k, step in enumerate(taken) if step.fell[1])
    assert verdicts[fall_step] == {1: False}
    (survived_step,) = [k for k, verdict in enumerate(verdicts) if 0 in verdict]
    assert verdicts[survived_step] == {0: True}
    assert taken[survived_step].states.time[0] - gentle.start_time >= PUSH_VERDICT_TIME
    assert taken[survived_step - 1].states.time[0] - gentle.start_time < PUSH_VERDICT_TIME
    assert records.finish(1, 0, False).ended == "fell"
