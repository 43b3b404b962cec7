"""An object kept in a worker process (``training/remote.py``): calls, errors raised here, a worker that dies."""

import pytest

from drillgym.training.remote import Remote


def test_calls_reach_the_object_in_its_process_and_its_errors_are_raised_here():
    remote = Remote(dict, {"holes": 3})
    try:
        assert remote.call("get", "holes") == 3
        remote.send("__setitem__", "holes", 4)  # a call in two halves: this process may work in between
        assert remote.receive() is None
        assert remote.call("get", "holes") == 4
        with pytest.raises(KeyError, match="missing"):
            remote.call("pop", "missing")
        assert remote.call("get", "holes") == 4  # the object outlives an error
    finally:
        remote.close()
    assert not remote._process.is_alive()


def test_an_object_that_cannot_be_built_raises_at_construction():
    with pytest.raises(TypeError):
        Remote(int, {"holes": "three"})


def test_a_dead_worker_is_reported_not_waited_for():
    remote = Remote(dict, {})
    remote._process.kill()
    remote._process.join()
    with pytest.raises(RuntimeError, match="worker process ended"):
        remote.call("get", "holes")
    remote.close()
