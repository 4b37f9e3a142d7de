"""run_tasks: a task that fails is reported with its name and the others go on."""

import pytest
from stns_experiments.config import ExperimentError
from stns_experiments.runner import run_tasks


def _task(task, progress):
    if task["key"] == "bad":
        raise ZeroDivisionError("division by zero in a learner")
    if task["key"] == "refused":
        raise ExperimentError("world: a refused value")
    progress(task["steps"])
    return {"key": task["key"], "twice": 2 * task["n"]}


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_failing_task_is_reported_and_the_others_go_on(jobs):
    tasks = [{"key": k, "steps": 5, "n": i} for i, k in enumerate(("a", "bad", "refused", "b"))]
    results, errors, interrupted = run_tasks(_task, tasks, jobs, "test", progress=False)
    assert not interrupted
    assert results == {"a": {"key": "a", "twice": 0}, "b": {"key": "b", "twice": 6}}
    assert set(errors) == {"bad", "refused"}
    assert errors["bad"].startswith("ZeroDivisionError: division by zero in a learner\n")
    assert "Traceback" in errors["bad"]  # where it failed, for the run's summary
    assert errors["refused"] == "world: a refused value"
