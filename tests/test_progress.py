"""Long simulation jobs log progress: unit k of n, simulated time, elapsed and remaining."""

import re

from granpipe.box.protocol import Progress as BoxProgress
from granpipe.drum.protocol import Progress as DrumProgress


def test_drum_progress_reports_replica_time_elapsed_and_remaining():
    lines = []
    progress = DrumProgress(n_replicas=4, expected_steps=100, log=lines.append, interval=0.0)
    progress.update(1, 50, 12.5, "onset window")
    assert re.fullmatch(
        r"replica 2 of 4: onset window, t = 12\.50 s; elapsed \d+ s, about \d+ s remaining",
        lines[-1],
    )
    # Half of one replica of four done: the estimate is 7x the elapsed time (>= 0).
    quiet = DrumProgress(n_replicas=4, expected_steps=100, log=lines.append, interval=3600.0)
    quiet.update(0, 10, 1.0, "settling")
    assert len(lines) == 1, "printed before its interval"
    progress.finish(1, "flowing after 3 s")
    assert lines[-1] == "replica 2 of 4 done: flowing after 3 s"


def test_box_progress_reports_period_time_elapsed_and_remaining():
    lines = []
    progress = BoxProgress(lines.append, total_steps=1000, label="N_l=10,Gamma=2", every=0.0)
    progress.update(250, "period 1 of 4", 6.28)
    assert re.fullmatch(
        r"N_l=10,Gamma=2: period 1 of 4, t = 6\.28 t0, elapsed \d+ s, remaining ~\d+ s",
        lines[-1],
    )
