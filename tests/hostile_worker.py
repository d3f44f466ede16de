"""Runs printapp commands for the hostile-input suite, one JSON case per line, in one process.

The process sets an address-space limit (4 GB by default) before importing anything, so a
command that tries to allocate past it fails as it would on a small machine; the suite
checks that such requests are refused first. Each case runs the CLI in-process (typer's
CliRunner) in its own folder; the answer says how it ended:

    {"code": exit code, "stdout": ..., "stderr": ..., "traceback": an exception escaped}

The memory budget (``--max-memory``) is reset between cases.
"""

from __future__ import annotations

import json
import os
import resource
import sys
import traceback

LIMIT_BYTES = int(os.environ.get("PRINTAPP_FUZZ_AS_LIMIT", 4 << 30))
MARK = "@@printapp-hostile@@ "
"""Prefix of the worker's answers: libraries below may print to stdout too."""


def main() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (LIMIT_BYTES, LIMIT_BYTES))
    from typer.testing import CliRunner

    from printapp import memory
    from printapp.cli import app

    runner = CliRunner()
    print(MARK + json.dumps({"ready": True}), flush=True)
    for line in sys.stdin:
        case = json.loads(line)
        memory.set_budget(None)
        os.chdir(case["cwd"])
        try:
            result = runner.invoke(app, case["args"], env=case.get("env"))
            escaped = result.exception is not None and not isinstance(result.exception, SystemExit)
            answer = {
                "code": result.exit_code,
                "stdout": result.stdout[-4000:],
                "stderr": result.stderr[-4000:],
                "traceback": escaped,
                "exception": "".join(traceback.format_exception(result.exception))[-4000:] if escaped else "",
            }
        except BaseException as exc:  # noqa: BLE001 (the suite reports whatever got through)
            answer = {
                "code": -1,
                "stdout": "",
                "stderr": repr(exc),
                "traceback": True,
                "exception": repr(exc),
            }
        print(MARK + json.dumps(answer), flush=True)


if __name__ == "__main__":
    main()
