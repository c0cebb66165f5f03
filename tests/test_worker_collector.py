"""The engine thread never runs Python's cyclic collector (occ_addon/worker.py): it is
off while jobs are handed over, back on (on the calling thread) once they ran, and a
collector the caller had turned off stays off.  worker.py imports nothing of Blender:
it is loaded from its file."""

import gc
import importlib.util
import os
import threading

import pytest

PATH = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "occ_addon", "worker.py")


@pytest.fixture
def worker():
    spec = importlib.util.spec_from_file_location("occ_worker_under_test", PATH)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    was = gc.isenabled()
    yield mod
    if was:
        gc.enable()
    else:
        gc.disable()


def test_the_collector_is_off_while_jobs_run_and_back_on_after(worker):
    gc.enable()
    engine = worker.EngineThread()
    go = threading.Event()
    seen = []
    try:
        first = engine.submit(lambda: (go.wait(10), seen.append(gc.isenabled())))
        second = engine.submit(lambda: seen.append(gc.isenabled()))
        assert not gc.isenabled()
        assert not first.done()
        go.set()
        first.result()
        second.result()
        assert seen == [False, False]
        assert gc.isenabled()                       # both ran: back on, here
        engine.run(lambda: None)
        assert gc.isenabled()
    finally:
        go.set()
        engine.shutdown()
    assert gc.isenabled()


def test_a_collector_the_caller_turned_off_stays_off(worker):
    gc.disable()
    engine = worker.EngineThread()
    try:
        engine.run(lambda: None)
        assert not gc.isenabled()
    finally:
        engine.shutdown()
    assert not gc.isenabled()


def test_a_failed_job_turns_it_back_on_too(worker):
    gc.enable()
    engine = worker.EngineThread()
    try:
        with pytest.raises(ZeroDivisionError):
            engine.run(lambda: 1 / 0)
        assert gc.isenabled()
    finally:
        engine.shutdown()
