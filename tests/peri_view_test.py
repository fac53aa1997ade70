#!/usr/bin/python3
"""tools/peri_view.py, reading a run that is still writing: the complete frames are those
frames.xdmf lists; a read that fails while the run writes a frame is done again, other failures
are not; a directory that is no run, or an unreadable frames.h5 of a finished run, ends the tool
at once with one message.

usage: peri_view_test.py SOURCE_DIR
"""
import os
import sys
import tempfile
import time

import h5py
import numpy as np

sys.path.insert(0, os.path.join(sys.argv[1], "tools"))
import peri_view  # noqa: E402

failures = []


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what)
    if not ok:
        failures.append(what)


def exit_message(fn):
    """The message of the SystemExit fn raises (None if it returns) and the seconds it took."""
    start = time.monotonic()
    try:
        fn()
    except SystemExit as e:
        return str(e), time.monotonic() - start
    return None, time.monotonic() - start


def fake_run(outdir, frames, listed):
    """frames.h5 with `frames` frames of 4 nodes; frames.xdmf naming the first `listed` of them."""
    os.makedirs(outdir, exist_ok=True)
    with h5py.File(os.path.join(outdir, "frames.h5"), "w") as f:
        f["scene"] = "name: fake\nbodies:\n  sheet: {kind: membrane}\n"
        f["mesh/reference_position"] = np.arange(12.0).reshape(4, 3)
        f["mesh/body"] = np.zeros(4)
        for k in range(frames):
            g = f.create_group(f"frames/{k:06d}")
            g.attrs["time"], g.attrs["step"] = 1e-6 * k, 10 * k
            g["position"] = np.arange(12.0).reshape(4, 3) + k
            g["damage"] = np.full(4, 0.1 * k)
    with open(os.path.join(outdir, "frames.xdmf"), "w") as x:
        x.write("".join(f'<DataItem Format="HDF">frames.h5:/frames/{k:06d}/damage</DataItem>\n'
                        for k in range(listed)))


with tempfile.TemporaryDirectory() as work:
    # A run writing its fourth frame: the xdmf lists three.
    live = os.path.join(work, "live")
    fake_run(live, frames=4, listed=3)
    run = peri_view.Run(live)
    check(run.frame_names == ["000000", "000001", "000002"], f"a live run's complete frames: {run.frame_names}")
    check(run.frame(-1)["step"] == 20, f"the last complete frame is step 20: {run.frame(-1)['step']}")
    check(peri_view.is_live(live), "no summary.json, frames.h5 just written: live")

    # A read failing as HDF5 does while the run flushes (once), then succeeding: read again.
    calls = []

    def flaky():
        peri_view.require_run(live)
        calls.append(1)
        if len(calls) == 1:
            raise KeyError("Unable to open object (bad heap free list)")
        return "read"

    check(peri_view.run_tool(flaky) == "read" and len(calls) == 2, f"live run: read again ({len(calls)} calls)")

    # The same failure in a finished run (summary.json present), and a KeyError of the tool's own:
    # raised at once.
    done = os.path.join(work, "done")
    fake_run(done, frames=2, listed=2)
    open(os.path.join(done, "summary.json"), "w").write("{}")
    check(not peri_view.is_live(done), "summary.json present: not live")
    for outdir, error, what in ((done, KeyError("Unable to open object (bad heap free list)"), "finished run"),
                                (live, KeyError("speed"), "a KeyError not from HDF5")):
        calls.clear()

        def failing():
            peri_view.require_run(outdir)
            calls.append(1)
            raise error

        try:
            peri_view.run_tool(failing)
            raised = False
        except KeyError:
            raised = True
        check(raised and len(calls) == 1, f"{what}: raised after {len(calls)} call(s)")

    # A run that failed (FAILED, no summary.json): not live (a read failure is raised at once, no
    # minute of retries), and the tools warn once that they draw a failed run's frames; a run
    # without summary.json that has stopped writing: warned of as unfinished.
    import contextlib
    import io
    failed = os.path.join(work, "failed")
    fake_run(failed, frames=2, listed=2)
    open(os.path.join(failed, "FAILED"), "w").write("energy balance error 0.5 at step 20 exceeds ...\n")
    check(not peri_view.is_live(failed), "FAILED present: not live")
    check(peri_view.run_state(failed) == "failed", f"FAILED present: state {peri_view.run_state(failed)}")
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        peri_view.Run(failed)
        peri_view.Run(failed)
    check(err.getvalue().count("warning: ") == 1 and "the run failed (energy balance error 0.5 at step 20" in err.getvalue(),
          f"failed run warned of once: {err.getvalue().strip()}")
    stopped = os.path.join(work, "stopped")
    fake_run(stopped, frames=2, listed=2)
    old = time.time() - 3600
    os.utime(os.path.join(stopped, "frames.h5"), (old, old))
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        peri_view.Run(stopped)
    check(peri_view.run_state(stopped) == "unfinished" and "the run did not finish" in err.getvalue(),
          f"stopped run warned of: {err.getvalue().strip()}")
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        peri_view.Run(done)
    check(err.getvalue() == "", f"a complete run: no warning ({err.getvalue().strip()})")

    # Not a run, and a finished run's truncated frames.h5: one message, no waiting.
    message, _ = exit_message(lambda: peri_view.Run(os.path.join(work, "missing")))
    check(message is not None and "no such directory" in message and "peridrive output directory" in message,
          f"missing directory: {message}")
    os.makedirs(os.path.join(work, "empty"))
    message, _ = exit_message(lambda: peri_view.scene_text(os.path.join(work, "empty")))
    check(message is not None and "no frames.h5" in message, f"directory without frames.h5: {message}")
    with open(os.path.join(done, "frames.h5"), "r+b") as f:
        f.truncate(1000)
    message, seconds = exit_message(lambda: peri_view.open_frames(done))
    check(message is not None and "cannot be read" in message and seconds < 5,
          f"finished run's truncated frames.h5: {message} ({seconds:.2f} s)")

sys.exit(1 if failures else 0)
