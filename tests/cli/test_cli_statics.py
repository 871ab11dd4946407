"""``qpik statics``: exit 0 with the torques on valid input, 2 with a reason otherwise."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import configuration_of

from qpik import statics
from qpik.cli import main

UR5E_Q = ["0", "-1.57", "1.57", "0", "0", "0"]


def _row(out: str, joint: str) -> list[str]:
    (line,) = [ln for ln in out.splitlines() if ln.split()[:1] == [joint]]
    return line.split()


def test_statics_prints_tau_gravity_and_holding(capsys):
    argv = [
        "statics",
        "ur5e",
        "--q",
        *UR5E_Q,
        "--force",
        "0",
        "0",
        "-20",
        "--torque",
        "0",
        "0",
        "1",
    ]
    assert main(argv) == 0
    out = capsys.readouterr().out
    configuration = configuration_of("ur5e", [float(x) for x in UR5E_Q])
    tau = statics.joint_torques(configuration, "ee", [0, 0, -20], [0, 0, 1])
    gravity = statics.gravity_torques(configuration)
    holding = statics.holding_torques(configuration, [("ee", [0, 0, -20], [0, 0, 1])])
    row = _row(out, "shoulder_lift_joint")
    np.testing.assert_allclose(
        [float(x) for x in row[1:4]], [tau[1], gravity[1], holding[1]], atol=1e-4
    )
    assert "holding = -(gravity + tau)" in out and "[-150, 150]" in out
    assert "within the actuator limits: yes" in out


def test_statics_local_axes_and_exceeded_limits(capsys):
    q = ["0", "-0.785398", "0", "-2.356194", "0", "1.570796", "0.785398"]
    argv = ["statics", "panda", "--q", *q, "--force", "0", "0", "-300", "--local"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    configuration = configuration_of("panda", [float(x) for x in q])
    tau = statics.joint_torques(configuration, "ee", [0, 0, -300], expressed_in="local")
    assert float(_row(out, "joint4")[1]) == pytest.approx(tau[3], abs=1e-4)
    assert "(local axes)" in out and "EXCEEDED" in out and "limits: no" in out


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["statics", "nope", "--force", "1", "0", "0"], "unknown robot 'nope'"),
        (["statics", "planar_2r", "--q", "1", "2", "3", "--force", "1", "0", "0"], "expected (2,)"),
        (["statics", "planar_2r", "--frame", "tip", "--force", "1", "0", "0"], "available sites: ee"),
        (["statics", "planar_2r", "--force", "nan", "0", "0"], "force[0] is nan"),
        (["statics", "planar_2r", "--force", "1", "0", "0", "--torque", "0", "inf", "0"], "torque[1] is inf"),
    ],
)  # fmt: skip
def test_statics_errors(argv, fragment, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert fragment in err and err.count("\n") == 1 and err.startswith("qpik statics: error:")


def test_statics_requires_a_force(capsys):
    with pytest.raises(SystemExit) as info:
        main(["statics", "planar_2r"])
    assert info.value.code == 2
    assert "--force" in capsys.readouterr().err


SPRUNG = """<mujoco><compiler angle="radian"/><worldbody><body name="l1">
  <joint name="j1" axis="0 1 0" range="-2 2"/><geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02"/>
  <body name="l2" pos="0.3 0 0"><joint name="j2" axis="0 1 0" range="-2 2" stiffness="5" springref="0.4"/>
   <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02"/><site name="ee" pos="0.3 0 0"/></body>
  </body></worldbody><keyframe><key qpos="0.1 0.2"/></keyframe></mujoco>"""


def test_statics_names_the_springs_holding_cancels_and_an_unnamed_keyframe(tmp_path, capsys):
    """h15's audit: holding = -(gravity + tau) did not add up on a model with joint springs
    (holding cancels them too): they are printed; an unnamed keyframe is listed as #K and
    chosen by --key #K (it showed as an empty name no one could give)."""
    path = tmp_path / "sprung.xml"
    path.write_text(SPRUNG)
    assert main(["statics", str(path), "--key", "#0", "--force", "0", "0", "0"]) == 0
    out = capsys.readouterr().out
    assert "q = [0.1 0.2]" in out
    (line,) = [ln for ln in out.splitlines() if "passive forces at rest" in ln]
    gravity, holding = (float(x) for x in _row(out, "j2")[2:4])
    spring = float(line.split("j2")[1])
    assert holding == pytest.approx(-(gravity + spring), abs=2e-4)
    assert spring == pytest.approx(-5.0 * (0.2 - 0.4), abs=1e-4)
    assert main(["statics", str(path), "--key", "nope", "--force", "0", "0", "0"]) == 2
    assert "#0 (unnamed)" in capsys.readouterr().err


def test_demo_takes_a_target_a_closed_linkage_can_reach(capsys):
    """h15's audit: on a gripper whose linkage connect constraints close (Menagerie's xArm
    hand), the demo's random target broke the constraints (random_q knows none) and every
    seed failed (reason constraint, exit 1): its linkage joints are now at qpos0, where the
    constraints hold. Here the trimmed xArm7 with its gripper."""
    from pathlib import Path

    import qpik
    from qpik.model.couplings import closed_chain_start, unheld_equalities, unheld_equality_errors

    path = Path(__file__).resolve().parents[1] / "data" / "menagerie" / "xarm7.xml"
    model = qpik.load_robot(path)
    unheld = unheld_equalities(model)
    assert unheld.size
    configuration = qpik.Configuration(model)
    for seed in range(3):
        q = configuration.random_q(np.random.default_rng(seed))
        fixed = closed_chain_start(model, q, configuration.lower, configuration.upper)
        assert max(unheld_equality_errors(model, fixed, unheld)) < max(
            unheld_equality_errors(model, q, unheld)
        )
        assert main(["demo", "--robot", str(path), "--seed", str(seed)]) == 0
