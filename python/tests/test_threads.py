"""The GIL is let go while a run works, runs from several threads are safe, and Ctrl-C
cancels a run."""

import signal
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import coarsen

# A run of a few seconds whose time goes to stages that report progress (the clustering):
# the demo mesh subdivided three times (1.3M faces) clustered into 5000 regions.
LONG = dict(
    vertices=5000,
    pipeline="uniform-cvt",
    params={"subdivide.faces_per_target_vertex": 0, "subdivide.times": 3},
)


@pytest.fixture
def no_preemption():
    """Threads switch only where one lets the GIL go of its own accord (a blocking call,
    a native call that releases it), never on the interpreter's timer."""
    before = sys.getswitchinterval()
    sys.setswitchinterval(1000)
    yield
    sys.setswitchinterval(before)


def test_python_code_runs_in_another_thread_while_a_remesh_works(demo, no_preemption):
    V, F = demo
    init = Path(coarsen.__file__).resolve()
    done = threading.Event()
    result = {}

    def work():
        result["out"] = coarsen.remesh(V, F, vertices=2000, pipeline="uniform-cvt")
        done.set()

    worker = threading.Thread(target=work)
    counter = 0
    seen_inside = 0
    worker.start()
    # With no preemption, this thread runs while `worker` is inside `coarsen.remesh` only if
    # the call lets the GIL go (the arrays are float64 / uint32 already: the Python half
    # converts nothing, so numpy lets nothing go before the native call).
    while not done.is_set():
        counter += 1
        frame = sys._current_frames().get(worker.ident)
        while frame is not None:
            if frame.f_code.co_name == "remesh" and Path(frame.f_code.co_filename).resolve() == init:
                seen_inside += 1
                break
            frame = frame.f_back
        time.sleep(0.001)
    worker.join()
    assert result["out"][2]["output_vertices"] == 2000
    assert seen_inside >= 2 and counter >= seen_inside, (seen_inside, counter)


def test_runs_in_two_threads_at_once_give_the_results_of_runs_in_turn(demo):
    V, F = demo
    jobs = [("uniform-cvt", 700), ("qem", 900)]
    alone = [coarsen.remesh(V, F, vertices=n, pipeline=p) for p, n in jobs]
    together = [None, None]

    def run(i):
        p, n = jobs[i]
        together[i] = coarsen.remesh(V, F, vertices=n, pipeline=p)

    threads = [threading.Thread(target=run, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for a, b in zip(alone, together):
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT to a thread is POSIX")
def test_ctrl_c_cancels_a_long_run_promptly(demo):
    V, F = demo
    main = threading.get_ident()
    sent = []

    def interrupt():
        sent.append(time.perf_counter())
        signal.pthread_kill(main, signal.SIGINT)

    timer = threading.Timer(0.4, interrupt)
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt) as e:
            coarsen.remesh(V, F, **LONG)
        stopped = time.perf_counter()
    finally:
        timer.cancel()
    assert sent, "the run ended before the interrupt was sent"
    # The run was stopped by the cancel flag, inside a stage (not finished, then
    # interrupted): the cancelled run's error is the interrupt's context.
    context = e.value.__context__
    assert isinstance(context, coarsen.CoarsenError), repr(context)
    assert str(context).startswith("cancelled during stage "), str(context)
    # Not a speed bar: a bound against a run that went on to its end (seconds more).
    assert stopped - sent[0] < 2.0, stopped - sent[0]
    # The package still works after a cancelled run.
    assert coarsen.remesh(V, F, vertices=300, pipeline="qem")[2]["output_vertices"] == 300
