"""Every bad input of the foundation raises a typed error that names the problem."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import configuration_of

import qpik


def test_unknown_robot_lists_available_names():
    with pytest.raises(qpik.UnknownRobot, match="planar_2r") as info:
        qpik.load_robot("no_such_robot")
    assert "panda" in info.value.available
    assert isinstance(info.value, qpik.QpikError)


def test_unknown_frame_lists_frames_of_that_type():
    configuration = configuration_of("ur5e")
    with pytest.raises(qpik.UnknownFrame, match="available sites: ee"):
        configuration.frame_pose("gripper")
    with pytest.raises(qpik.UnknownFrame, match="tool0"):
        configuration.frame_jacobian("gripper", "body")


def test_unknown_frame_type():
    configuration = configuration_of("ur5e")
    with pytest.raises(qpik.UnknownFrameType, match="body, site, geom"):
        configuration.frame_pose("ee", "joint")


def test_unknown_frame_through_mink_task_is_typed():
    import mink

    configuration = configuration_of("ur5e")
    task = mink.FrameTask("gripper", "site", position_cost=1.0, orientation_cost=1.0)
    with pytest.raises(qpik.UnknownFrame):
        task.set_target_from_configuration(configuration)


@pytest.mark.parametrize(
    "q, fragment",
    [
        ([0.0, 0.0, 0.0], r"shape \(3,\), expected \(2,\)"),
        ([0.0, np.nan], r"q\[1\] \(joint 'q2'\) is nan"),
        ([np.inf, 0.0], r"q\[0\] \(joint 'q1'\) is inf"),
    ],
)
def test_bad_configuration_names_the_index(q, fragment):
    with pytest.raises(qpik.InvalidConfiguration, match=fragment):
        configuration_of("planar_2r", q)
    configuration = configuration_of("planar_2r")
    with pytest.raises(qpik.InvalidConfiguration, match=fragment):
        configuration.update(q)


def test_bad_velocity():
    configuration = configuration_of("planar_2r")
    with pytest.raises(qpik.InvalidConfiguration, match=r"v\[1\]"):
        configuration.integrate([0.0, np.nan], 0.1)


def test_unreadable_files_name_the_path(tmp_path):
    missing = tmp_path / "missing.xml"
    with pytest.raises(qpik.RobotFileError, match="missing.xml"):
        qpik.load_robot(missing)
    broken = tmp_path / "broken.urdf"
    broken.write_text("<robot name='x'><link name='a'>")
    with pytest.raises(qpik.RobotFileError, match="broken.urdf.*not well-formed"):
        qpik.load_robot(broken)
    wrong_root = tmp_path / "wrong.xml"
    wrong_root.write_text("<html/>")
    with pytest.raises(qpik.RobotFileError, match="expected <mujoco> or <robot>"):
        qpik.load_robot(wrong_root)
    bad_mjcf = tmp_path / "bad.xml"
    bad_mjcf.write_text(
        "<mujoco><worldbody><body><joint type='nonsense'/></body></worldbody></mujoco>"
    )
    with pytest.raises(qpik.RobotFileError, match="bad.xml"):
        qpik.load_robot(bad_mjcf)


def test_erd_without_the_extra_names_it(monkeypatch):
    from importlib import metadata

    def missing(name):
        raise metadata.PackageNotFoundError(name)

    monkeypatch.setattr(metadata, "distribution", missing)
    with pytest.raises(qpik.MissingExtra, match=r"qpik\[robots\]"):
        qpik.load_robot("erd:panda")


# ------------------------------------------------------------ mink's exceptions (issue 14)
MINK_COUNTERPARTS = [
    ("JointLimitViolation", "NotWithinConfigurationLimits"),
    ("UnknownFrame", "InvalidFrame"),
    ("UnknownFrameType", "UnsupportedFrame"),
    ("NoSolutionFound", "NoSolutionFound"),
    ("InvalidTarget", "InvalidTarget"),
    ("TargetNotSet", "TargetNotSet"),
    ("IntegrationTimestepNotSet", "IntegrationTimestepNotSet"),
    ("InvalidGain", "InvalidGain"),
    ("InvalidDamping", "InvalidDamping"),
    ("InvalidConstraint", "InvalidConstraint"),
    ("TaskDefinitionError", "TaskDefinitionError"),
    ("LimitDefinitionError", "LimitDefinitionError"),
    ("InvalidKeyframe", "InvalidKeyframe"),
    ("InvalidMocapBody", "InvalidMocapBody"),
]


def _mink_args(mink_name: str, model):
    """Arguments as mink's own code constructs its exception."""
    return {
        "NotWithinConfigurationLimits": dict(
            joint_id=2, value=4.0, lower=-3.0, upper=3.0, model=model
        ),
        "InvalidFrame": ("gripper", "site", model),
        "UnsupportedFrame": ("joint", ["body", "geom", "site"]),
        "NoSolutionFound": ("daqp",),
        "TargetNotSet": ("FrameTask",),
        "IntegrationTimestepNotSet": ("KineticEnergyRegularizationTask",),
        "InvalidKeyframe": ("crouch", model),
        "InvalidMocapBody": ("base_link", model),
    }.get(mink_name, ("a message",))


@pytest.mark.parametrize("ours, theirs", MINK_COUNTERPARTS)
def test_each_error_is_its_mink_counterpart_built_minks_way(ours, theirs):
    import mink

    model = qpik.load_robot("ur5e")
    cls, mink_cls = getattr(qpik, ours), getattr(mink, theirs)
    assert issubclass(cls, mink_cls) and issubclass(cls, qpik.QpikError)
    assert ours in qpik.errors.__all__
    args = _mink_args(theirs, model)
    error = cls(**args) if isinstance(args, dict) else cls(*args)
    with pytest.raises(mink_cls):
        raise error
    assert str(error)  # a message, never an empty one
    # Round trip through pickle (errors cross process boundaries in solve_many).
    import pickle

    copy = pickle.loads(pickle.dumps(error))
    assert type(copy) is cls and str(copy) == str(error)
    assert {k: v for k, v in vars(copy).items()} == {k: v for k, v in vars(error).items()}


def test_joint_limit_violation_both_ways_keeps_fields():
    model = qpik.load_robot("ur5e")
    theirs = qpik.JointLimitViolation(2, 4.0, -3.0, 3.0, model)  # mink's positional form
    assert (theirs.joint, theirs.index, theirs.joint_id) == ("elbow_joint", 2, 2)
    assert (theirs.value, theirs.lower, theirs.upper) == (4.0, -3.0, 3.0)
    ours = qpik.JointLimitViolation("elbow_joint", 2, 4.0, -3.0, 3.0)
    assert str(ours) == str(theirs) and ours.joint_id is None
    with pytest.raises(TypeError):
        qpik.JointLimitViolation("elbow_joint", 2)  # neither signature


def test_unknown_frame_built_minks_way_lists_the_names():
    model = qpik.load_robot("ur5e")
    error = qpik.UnknownFrame("gripper", "site", model)
    assert error.available == ["ee"] and "available sites: ee" in str(error)
    assert "tool0" in qpik.UnknownFrame(99, "body", model).available


def test_mink_messages_where_tests_compare_them():
    import mink

    assert str(qpik.NoSolutionFound("daqp")) == str(mink.NoSolutionFound("daqp"))
    assert str(qpik.NoSolutionFound("osqp", "max_iter", 1)).endswith("priority level 1: max_iter")
    assert str(qpik.TargetNotSet("FrameTask")).startswith(str(mink.TargetNotSet("FrameTask")))
    unsupported = qpik.UnknownFrameType("joint", ["body", "geom", "site"])
    assert unsupported.frame_type == "joint" and unsupported.supported == ["body", "geom", "site"]


@pytest.mark.parametrize(
    "error",
    [
        qpik.UnknownRobot("x", ["panda"]),
        qpik.RobotFileError("robot.xml", "broken"),
        qpik.ProblemFileError("p.toml", "targets", "a table"),
        qpik.InvalidConfiguration("bad", index=3),
        qpik.UnknownFrameType("unknown frame type 'joint'"),
    ],
)
def test_qpik_errors_pickle(error):
    import pickle

    copy = pickle.loads(pickle.dumps(error))
    assert type(copy) is type(error) and str(copy) == str(error) and vars(copy) == vars(error)


def test_a_start_outside_the_limits_names_where_it_came_from():
    """The robot's own q as the default start is named as the robot (the argument the
    user passed), an explicit q0 as q0; both pickle with the same message."""
    import pickle

    model = qpik.load_robot("panda")
    configuration = qpik.Configuration(model)
    q = configuration.q.copy()
    q[3] = 0.0  # joint4's range is [-3.07, -0.07]
    configuration.update(q)
    with pytest.raises(qpik.JointLimitViolation, match=r"^robot \(its configuration") as caught:
        qpik.solve(configuration, {"ee": np.array([0.4, 0.0, 0.4])})
    assert str(pickle.loads(pickle.dumps(caught.value))) == str(caught.value)
    with pytest.raises(qpik.JointLimitViolation, match=r"^q0: "):
        qpik.solve(model, {"ee": np.array([0.4, 0.0, 0.4])}, q0=q)
