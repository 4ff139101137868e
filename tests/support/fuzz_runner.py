"""Run `wcs` commands in forked children, each under a timeout and an address-space limit, and
classify how each one ended.

`python tests/support/fuzz_runner.py JOBS.json RESULTS.json`: JOBS is a list of {"id", "argv", "cwd"};
RESULTS gets, per job, {"id", "code", "signal", "stderr", "wall", "maxrss_gb"}. The server
imports `wcs` once and forks one child per job (a fresh interpreter per job would spend 2.5 s of
its imports on every mutant); the child lowers its RLIMIT_AS, runs `wcs.cli.main(argv)` and
exits with its code. A child past the timeout is killed (signal 9, `"timeout": true`).
"""
from __future__ import annotations

import json
import os
import resource
import signal
import sys
import time
import traceback

TIMEOUT = 60.0                 # s a job may take (a small 3D check takes under 10 s on a loaded machine)
ADDRESS_SPACE = 4 * 2**30      # bytes: RLIMIT_AS of a job (a small check maps under 1.5 GB)


def _child(job: dict, out: str, err: str) -> None:
    """In the forked child: the job's command with stdout and stderr to files; never returns."""
    code = 1
    try:
        resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))
        for fd, name in ((1, out), (2, err)):
            os.dup2(os.open(name, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600), fd)
        os.chdir(job["cwd"])
        from wcs.cli import main
        code = main(job["argv"] + ["--verbose"])
    except SystemExit as e:                        # argparse
        code = e.code if isinstance(e.code, int) else 1
    except BaseException:                          # noqa: BLE001 - reported as the traceback it is
        traceback.print_exc()
        code = 1
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)


def run_job(job: dict, folder: str, timeout: float = TIMEOUT) -> dict:
    """Fork, run `job` in the child, wait at most `timeout` seconds."""
    out, err = os.path.join(folder, f"{job['id']}.out"), os.path.join(folder, f"{job['id']}.err")
    sys.stdout.flush()
    sys.stderr.flush()
    t0 = time.perf_counter()
    pid = os.fork()
    if pid == 0:
        _child(job, out, err)
    timed_out = False
    while True:
        done, status, usage = os.wait4(pid, os.WNOHANG)
        if done:
            break
        if time.perf_counter() - t0 > timeout:
            os.kill(pid, signal.SIGKILL)
            _, status, usage = os.wait4(pid, 0)
            timed_out = True
            break
        time.sleep(0.01)
    with open(err, encoding="utf-8", errors="replace") as f:
        stderr = f.read()[-4000:]
    return {"id": job["id"], "code": os.waitstatus_to_exitcode(status) if os.WIFEXITED(status) else None,
            "signal": os.WTERMSIG(status) if os.WIFSIGNALED(status) else None, "timeout": timed_out,
            "stderr": stderr, "wall": time.perf_counter() - t0, "maxrss_gb": usage.ru_maxrss / 2**20}


def main(jobs_file: str, results_file: str) -> None:
    import wcs.cli, wcs.app.commands, wcs.app.solve, wcs.model.evaluation, wcs.study   # noqa: E401,F401 - imported once, before forking
    with open(jobs_file, encoding="utf-8") as f:
        jobs = json.load(f)
    folder = os.path.dirname(os.path.abspath(results_file))
    results = [run_job(job, folder) for job in jobs]
    with open(results_file, "w", encoding="utf-8") as f:
        json.dump(results, f)


if __name__ == "__main__":
    main(*sys.argv[1:3])
