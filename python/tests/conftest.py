"""A real run of `configs/smoke.toml`, started with the built launcher, for the tests that
need one (the `run` fixture).

The launcher is `target/debug/lavatube` of this checkout, or the one in `$LAVATUBE_BIN_DIR`;
without it those tests are skipped. The run directory goes to pytest's tmp_path.
"""

import json
import os
import re
import subprocess
import threading
import uuid
from collections import namedtuple
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: Seconds for the whole run, after which a watchdog kills the launcher (its processes
#: follow it).
LIMIT_S = 180

#: `dir` is the run directory, `tmp_path/<id>`.
Run = namedtuple("Run", "id proc dir")


@pytest.fixture
def bin_dir():
    """The directory of the built binaries (`lavatube`, `sim-proc`, …)."""
    found = Path(os.environ.get("LAVATUBE_BIN_DIR", ROOT / "target" / "debug"))
    if not (found / "lavatube").is_file():
        pytest.skip(f"no launcher in {found}: build the workspace or set LAVATUBE_BIN_DIR")
    return found


@pytest.fixture
def run(tmp_path, bin_dir):
    """A smoke run writing under tmp_path; the launcher is stopped at the end if still up."""
    launcher = bin_dir / "lavatube"
    # `run.out-dir` is relative to the working directory: point it at tmp_path instead.
    config, n = re.subn(r"(?m)^out-dir = .*$", f"out-dir = {json.dumps(str(tmp_path))}",
                        (ROOT / "configs" / "smoke.toml").read_text())
    assert n == 1, "configs/smoke.toml no longer sets run.out-dir"
    (tmp_path / "smoke.toml").write_text(config)
    run_id = f"py-{uuid.uuid4().hex[:12]}"
    log = tmp_path / "launcher.log"
    with log.open("w") as out:
        proc = subprocess.Popen([launcher, "run", "--config", tmp_path / "smoke.toml",
                                 "--run-id", run_id, "--quiet"],
                                cwd=tmp_path, stdout=out, stderr=subprocess.STDOUT)
    watchdog = threading.Timer(LIMIT_S, proc.kill)
    watchdog.start()
    try:
        yield Run(run_id, proc, tmp_path / run_id)
    finally:
        watchdog.cancel()
        proc.terminate()  # the launcher stops its processes and removes the run's memory
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        print(log.read_text())  # shown when the test fails
