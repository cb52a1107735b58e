"""The set-up's warm-up (`python -m ita.warmup`, run by setup.sh): it must keep working,
or a fresh set-up fails."""

from __future__ import annotations

from ita import warmup


def test_the_warm_up_runs_every_step_and_says_so(capsys):
    warmup.main()
    lines = capsys.readouterr().out.splitlines()
    assert [line.split(" kernels")[0] for line in lines[:-1]] == [f"[setup] compiled the {name}"
                                                                  for name, _ in warmup.STEPS]
    assert {"ordering", "paths", "range frames"} <= {name for name, _ in warmup.STEPS}
    assert lines[-1].startswith("[setup] kernels compiled in")
