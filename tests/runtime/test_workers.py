"""td2adaptor.runtime.workers: threads kept for the next task (the goal followers of the edge node)."""

from __future__ import annotations

import threading

from td2adaptor.runtime.workers import Workers


def _run(workers: Workers, task: threading.Event | None = None) -> tuple[threading.Event, list[str]]:
    """Submit a task that records its thread's name and waits for `task` (if given); its end event."""
    ended, names = threading.Event(), []

    def body() -> None:
        names.append(threading.current_thread().name)
        if task is not None:
            assert task.wait(10)
        ended.set()

    workers.submit(body)
    return ended, names


def _idle(workers: Workers, count: int) -> bool:
    with workers._cond:
        return workers._cond.wait_for(lambda: workers._idle == count, 10)


def test_a_finished_worker_takes_the_next_task() -> None:
    workers = Workers("reuse")
    first, first_names = _run(workers)
    assert first.wait(10) and _idle(workers, 1)
    second, second_names = _run(workers)
    assert second.wait(10)
    assert first_names == second_names == ["reuse-1"]


def test_tasks_that_wait_run_at_once_each_in_a_thread_of_its_own() -> None:
    workers, release = Workers("wide"), threading.Event()
    runs = [_run(workers, release) for _ in range(5)]
    try:
        with workers._cond:
            assert workers._started == 5
    finally:
        release.set()
    assert all(ended.wait(10) for ended, _ in runs)
    assert sorted(names[0] for _, names in runs) == [f"wide-{i}" for i in range(1, 6)]


def test_a_failing_task_does_not_cost_the_worker() -> None:
    workers = Workers("sturdy")

    def boom() -> None:
        raise RuntimeError("a task's own failure")

    workers.submit(boom)
    assert _idle(workers, 1)
    ended, names = _run(workers)
    assert ended.wait(10) and names == ["sturdy-1"]


def test_an_idle_worker_ends_after_its_idle_timeout() -> None:
    workers = Workers("brief", idle_timeout=0.05)
    ended, names = _run(workers)
    assert ended.wait(10) and names == ["brief-1"] and _idle(workers, 0)  # brief-1 waited 50 ms, then ended
    again, again_names = _run(workers)
    assert again.wait(10) and again_names == ["brief-2"]
