"""Episodes of the per-tick hybrid controller and baseline equal those of the
whole-segment simulation they replaced.

``tests/data/episode_fingerprints.json`` was made by ``tools/episode_fingerprints.py``
on the code that simulated whole policies in one compiled loop (commit fbcb505). The
same cases run here through :meth:`HybridController.step` on a
:class:`gracenav.sim.Model3DPlant`: the shipped scenarios, pushes (caught by library
policies and by catches), balancing mode with and without resumption, a drag, moving
obstacles and model mismatch give the same status, length, switch events, goals and
replans, and the same states, inputs and references (sampled once a second) within
1e-9. (When the per-tick controller was introduced they were equal bit for bit, as the
digests in the file show on the machine that made it; a test of the last bits would
fail on another BLAS or CPU for no reason, so the digests are not asserted.) The
decoupled baseline's references differ by ~1e-13 from run to run of the same code (the
shape planner's results depend on the process's history) and by up to 3.3e-9 from one
machine to another of the same kind (measured on fig5 and fig7, with the code of the
file's commit too), so they are compared within 1e-7. Position noise is now
drawn once per tick for the whole run and put on the measured state the whole
controller sees (before, it was drawn anew for every segment from the same seed and
reached the control law only): those runs are compared by outcome.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tools"))

import episode_fingerprints as ef  # noqa: E402

REFERENCE = json.loads((ROOT / "tests" / "data" / "episode_fingerprints.json").read_text())


def _final(fp: dict) -> np.ndarray:
    return np.array([float.fromhex(v) for v in fp["final_state"]])


@pytest.mark.slow
def test_episodes_equal_the_whole_segment_simulation(monkeypatch: pytest.MonkeyPatch) -> None:
    # The reference was made on the nonic palette, the default then.
    monkeypatch.setenv("GRACENAV_PALETTE", "nonic")
    same = 0
    for name, run in ef.cases():
        got = [ef.fingerprint(ep) for ep in run()]
        want = REFERENCE[name]
        assert len(got) == len(want), name
        for a, b in zip(got, want, strict=True):
            assert a["status"] == b["status"], name
            assert a["time_off_grid"] == 0.0, name
            if name == "noise":
                assert abs(a["samples"] - b["samples"]) <= 0.02 * b["samples"], name
                continue
            assert a["events"] == b["events"], name
            assert a["goals_reached"] == b["goals_reached"], name
            assert a["samples"] == b["samples"], name
            assert a["replans"] == b["replans"] and a["captures"] == b["captures"], name
            atol = 1e-7 if name.endswith("/decoupled") else 1e-9
            np.testing.assert_allclose(_final(a), _final(b), rtol=0, atol=atol, err_msg=name)
            np.testing.assert_allclose(
                np.array(a["trace"]), np.array(b["trace"]), rtol=0, atol=atol, err_msg=name
            )
            if not name.endswith("/decoupled"):
                same += 1
    assert same == 28  # every hybrid-controller episode without noise
