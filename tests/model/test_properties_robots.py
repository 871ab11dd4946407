"""Properties of qpik.load_robot on malformed MJCF / URDF text and odd names, and of the
statics on any input (issue 13): a typed error, or a model whose kinematics and statics
are finite, and finite torques / wrenches."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from properties_common import (
    ROBOTS,
    any_float,
    assert_finite,
    load,
    not_a_number,
    props,
    q_from_unit,
    typed_or_value,
)

import qpik
from qpik import statics

#: Attribute values: numbers in every form, and things that are not numbers.
attribute = st.one_of(
    st.sampled_from(
        [
            "nan",
            "inf",
            "-inf",
            "1e400",
            "-1",
            "0",
            "",
            "abc",
            "1e300",
            "1e-300",
            "nan 0 0",
            "0 0 0",
            "1 2",
            "1 0 0 0 0",
            "-3 3",
            "3 -3",
            "0.3 0 0",
        ]
    ),
    st.lists(any_float, min_size=1, max_size=4).map(lambda xs: " ".join(repr(x) for x in xs)),
)
urdf_joint_types = st.sampled_from(
    ["revolute", "continuous", "prismatic", "fixed", "floating", "planar", "bogus"]
)
mjcf_joint_types = st.sampled_from(["hinge", "slide", "ball", "free", "bogus"])


@st.composite
def urdf_text(draw) -> str:
    n = draw(st.integers(0, 3))
    links = ['<link name="base"/>']
    joints = []
    for i in range(n):
        a = draw(
            st.fixed_dictionaries(
                {},
                optional={
                    k: attribute
                    for k in (
                        "xyz",
                        "axis",
                        "lower",
                        "upper",
                        "mass",
                        "ixx",
                        "velocity",
                        "effort",
                        "radius",
                    )
                },
            )
        )
        links.append(
            f'<link name="l{i}"><inertial><mass value="{a.get("mass", "1")}"/>'
            f'<inertia ixx="{a.get("ixx", "0.01")}" iyy="0.01" izz="0.01" ixy="0" ixz="0" '
            f'iyz="0"/></inertial><collision><geometry><cylinder radius="{a.get("radius", "0.03")}"'
            ' length="0.3"/></geometry></collision></link>'
        )
        kind = draw(urdf_joint_types)
        limit = (
            f'<limit lower="{a.get("lower", "-2")}" upper="{a.get("upper", "2")}" '
            f'effort="{a.get("effort", "10")}" velocity="{a.get("velocity", "1")}"/>'
        )
        joints.append(
            f'<joint name="j{i}" type="{kind}"><parent link="{"base" if i == 0 else f"l{i - 1}"}"/>'
            f'<child link="l{i}"/><origin xyz="{a.get("xyz", "0 0 0.3")}" rpy="0 0 0"/>'
            f'<axis xyz="{a.get("axis", "0 0 1")}"/>{limit if draw(st.booleans()) else ""}</joint>'
        )
    return f'<?xml version="1.0"?><robot name="r">{"".join(links)}{"".join(joints)}</robot>'


@st.composite
def mjcf_text(draw) -> str:
    n = draw(st.integers(0, 3))
    bodies = []
    for i in range(n):
        a = draw(
            st.fixed_dictionaries(
                {},
                optional={
                    k: attribute for k in ("pos", "axis", "range", "size", "mass", "quat", "gear")
                },
            )
        )
        kind = draw(mjcf_joint_types)
        joint = f'<joint name="j{i}" type="{kind}"'
        if kind in ("hinge", "slide"):
            joint += f' axis="{a.get("axis", "0 0 1")}"'
            if draw(st.booleans()):
                joint += f' range="{a.get("range", "-2 2")}" limited="true"'
        joint += "/>" if kind != "free" or i == 0 else ""
        if kind == "free" and i > 0:
            joint = ""
        quat = f' quat="{a["quat"]}"' if "quat" in a else ""
        mass = f' mass="{a["mass"]}"' if "mass" in a else ""
        bodies.append(
            f'<body name="b{i}" pos="{a.get("pos", "0.3 0 0")}"{quat}>{joint}'
            f'<geom type="capsule" fromto="0 0 0 0.3 0 0" size="{a.get("size", "0.03")}"'
            f"{mass}/>"
        )
    site = '<site name="ee" pos="0.3 0 0"/>'
    body = "".join(bodies) + site + "</body>" * n if n else f'<body name="b">{site}</body>'
    actuator = ""
    if n and draw(st.booleans()):
        actuator = (
            f'<actuator><motor joint="j0" gear="{draw(attribute)}" ctrlrange="-1 1" '
            'ctrllimited="true"/></actuator>'
        )
    return f"<mujoco><worldbody>{body}</worldbody>{actuator}</mujoco>"


def exercise(model) -> None:
    """A model that loaded has finite kinematics, statics and IK."""
    configuration = qpik.Configuration(model)
    assert_finite(configuration.q, "qpos0")
    assert_finite(statics.gravity_torques(configuration), "gravity_torques")
    for site in qpik.frame_names(model, "site")[:1]:
        assert_finite(configuration.frame_pose(site, "site"), "frame_pose")
        assert_finite(configuration.frame_jacobian(site, "site"), "frame_jacobian")
        if model.nv:
            start = configuration.mid_q()
            target = qpik.Configuration(model, start).frame_pose(site, "site")[0]
            result, _ = typed_or_value(
                lambda s=site, t=target, q=start: qpik.solve(
                    model, {s: t}, q0=q, restarts=0, max_iters=20
                )
            )
            if result is not None:
                assert_finite(result, "solve")


@props(40)
@given(
    text=st.one_of(urdf_text(), mjcf_text()),
    corrupt=st.sampled_from([None, None, None, "non_utf8", "truncate", "bom"]),
)
def test_malformed_robot_files_raise_robot_file_error_or_load_finite(
    tmp_path_factory, text, corrupt
):
    data = text.encode()
    if corrupt == "non_utf8":
        data = data.replace(b'name="', b'name="\xff\xfe', 1)
    elif corrupt == "truncate":
        data = data[: len(data) // 2]
    elif corrupt == "bom":
        data = b"\xef\xbb\xbf" + data
    suffix = ".urdf" if text.lstrip().startswith("<?xml") else ".xml"
    path = tmp_path_factory.mktemp("robot") / f"robot{suffix}"
    path.write_bytes(data)
    model, error = typed_or_value(lambda: qpik.load_robot(path))
    if error is not None:
        assert isinstance(error, (qpik.RobotFileError, qpik.UnknownRobot)), repr(error)
        return
    exercise(model)


@props(20)
@given(
    name=st.one_of(
        st.sampled_from(
            [
                "x" * 300,
                "",
                "erd:",
                "erd:nope",
                "/",
                ".",
                "robots",
                "a\x00b",
                "nope.xml",
                "erd:" + "y" * 300,
                "/dev/null",
                "PANDA",
                "panda ",
            ]
        ),
        st.text(max_size=30),
    )
)
def test_robot_names_load_or_raise_a_typed_error(name):
    model, error = typed_or_value(lambda: qpik.load_robot(name))
    if error is None:
        exercise(model)


vector3 = st.one_of(
    st.lists(st.floats(-100, 100), min_size=3, max_size=3),
    st.lists(any_float, min_size=3, max_size=3),
    st.lists(any_float, max_size=4),
    not_a_number,
)


@props(40)
@given(
    robot=st.sampled_from(ROBOTS),
    q_unit=st.lists(st.floats(0, 1), min_size=7, max_size=7),
    force=vector3,
    torque=st.one_of(st.none(), vector3),
    direction=vector3,
    frame=st.sampled_from(["ee", "ee", "nope", 99]),
    frame_type=st.sampled_from(["site", "site", "body", "bogus"]),
    expressed_in=st.sampled_from(["world", "local", "bogus"]),
    rcond=st.one_of(st.just(1e-10), any_float),
    gravity=st.booleans(),
)
def test_statics_give_a_typed_error_or_finite_torques(
    robot, q_unit, force, torque, direction, frame, frame_type, expressed_in, rcond, gravity
):
    model = load(robot)
    configuration = qpik.Configuration(model, q_from_unit(model, q_unit))
    tau, _ = typed_or_value(
        lambda: statics.joint_torques(configuration, frame, force, torque, frame_type, expressed_in)
    )
    if tau is not None:
        assert_finite(tau, "joint_torques")
    holding, _ = typed_or_value(
        lambda: statics.holding_torques(
            configuration, [((frame, frame_type), force, torque)], gravity
        )
    )
    if holding is not None:
        assert_finite(holding, "holding_torques")
    estimate, _ = typed_or_value(
        lambda: statics.wrench_from_torques(
            configuration,
            frame,
            np.resize(
                np.asarray(
                    force
                    if isinstance(force, list) and all(isinstance(x, float) for x in force)
                    else [0.0],
                    dtype=float,
                ),
                model.nv,
            ),
            frame_type,
            rcond,
        )
    )
    if estimate is not None:
        assert_finite(estimate, "wrench_from_torques")
    payload, _ = typed_or_value(
        lambda: statics.max_payload(configuration, frame, direction, None, frame_type, gravity)
    )
    if payload is not None:  # force: inf when nothing binds, 0 when infeasible (documented)
        assert_finite(payload, "max_payload", allow=(".force", ".interval"))
        assert not np.isnan(payload.force) and payload.force >= 0.0
        assert payload.feasible or payload.force == 0.0
