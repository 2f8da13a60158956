"""A second engine: the product's MJCF export loaded in MuJoCo, its loop closed by the
``connect`` equality, checked against the product's kinematics and inverse dynamics.

MuJoCo's inverse dynamics work in the tree's 5 coordinates. The actuated ones are mapped
through S = [I; -pinv(J_p) J_a] from MuJoCo's own connect Jacobian (J = jac(tip_C) -
jac(tip_D), split into actuated and passive columns; J_p is 3 x 2 and rank 2, its plane-normal
row zero, hence pinv): qvel = S qd, the passive accelerations -pinv(J_p) (J_a qdd + Jdot
qvel) (Jdot qvel by a central difference of J along qvel), then tau = S^T qfrc_inverse, where
S^T cancels the constraint force J^T lambda exactly. Nothing of the product's dynamics enters
but the exported masses and lengths. Tolerance 1e-6 relative: the Jdot difference (h = 1e-6)
is good to ~1e-10, the rest is rounding; a wrong term is of order 1.
"""

from __future__ import annotations

import numpy as np
import pytest
from dynamics_reference import random_postures

from planner import Design, forward_batch
from planner.dynamics import Inertia, LinkInertia, inverse_dynamics
from planner.dynamics.mjcf import JOINT_NAMES, mjcf_qpos, to_mjcf

mujoco = pytest.importorskip("mujoco")

ODD = Inertia(
    proximal=LinkInertia(0.7, 0.3, 0.004, 0.0075),
    distal=LinkInertia(1.1, 0.65, 0.02, 0.001),
    payload_mass=0.8,
    base_inertia=0.03,
    rotor=(0.002, 0.001, 0.003),
)
GRAVITY = (0.7, -2.0, -9.81)


def _load(design: Design, inertia: Inertia, mode: str = "+"):
    xml = to_mjcf(design, inertia, gravity=GRAVITY, assembly_mode=mode)
    model = mujoco.MjModel.from_xml_string(xml)
    dofs = [int(model.joint(name).dofadr[0]) for name in JOINT_NAMES]
    return model, mujoco.MjData(model), dofs


def _loop_jacobian(model, data, qpos: np.ndarray) -> np.ndarray:
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    jc, jd = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    mujoco.mj_jacSite(model, data, jc, None, model.site("tip_C").id)
    mujoco.mj_jacSite(model, data, jd, None, model.site("tip_D").id)
    return jc - jd


def _mujoco_inverse(model, data, dofs, qpos, qd, qdd):
    """(tau (3,), M_actuated (3, 3)) by MuJoCo for one posture."""
    act, pas = [dofs[0], dofs[1], dofs[3]], [dofs[2], dofs[4]]
    j = _loop_jacobian(model, data, qpos)
    pinv = np.linalg.pinv(j[:, pas])
    s = np.zeros((model.nv, 3))
    s[act] = np.eye(3)
    s[pas] = -pinv @ j[:, act]
    qvel = s @ qd
    h = 1e-6
    jdot_v = (
        (
            _loop_jacobian(model, data, qpos + h * qvel)
            - _loop_jacobian(model, data, qpos - h * qvel)
        )
        @ qvel
        / (2 * h)
    )
    qacc = np.zeros(model.nv)
    qacc[act] = qdd
    qacc[pas] = -pinv @ (j[:, act] @ qdd + jdot_v)
    data.qpos[:] = qpos
    data.qvel[:] = qvel
    data.qacc[:] = qacc
    mujoco.mj_inverse(model, data)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    return s.T @ data.qfrc_inverse, s.T @ full @ s


@pytest.mark.parametrize("mode", ["+", "-"])
@pytest.mark.parametrize(
    "design", [Design.default(), Design(L0=0.3, L1=0.25, L2=0.45)], ids=["default", "skewed"]
)
def test_inverse_dynamics_and_mass_matrix_agree_with_mujoco(design: Design, mode: str) -> None:
    rng = np.random.default_rng(4)
    q = random_postures(design, mode, 12, seed=9)
    qd = rng.normal(0, 1.5, size=q.shape)
    qdd = rng.normal(0, 4.0, size=q.shape)
    for inertia in (Inertia.default(design), ODD):
        model, data, dofs = _load(design, inertia, mode)
        ours = inverse_dynamics(
            design, inertia, q, qd, qdd, assembly_mode=mode, gravity=GRAVITY, with_mass_matrix=True
        )
        qpos = mjcf_qpos(design, q, mode)
        for i in range(q.shape[0]):
            tau, m = _mujoco_inverse(model, data, dofs, qpos[i], qd[i], qdd[i])
            np.testing.assert_allclose(ours.tau[i], tau, rtol=0, atol=1e-6 * np.max(np.abs(tau)))
            np.testing.assert_allclose(ours.mass_matrix[i], m, rtol=0, atol=1e-6 * np.max(m))


def test_exported_loop_closes_where_the_product_puts_p() -> None:
    """Load the export; at random postures of both assembly modes (theta1 anywhere) both tips
    sit on the product's P (to 1e-12 m), the home keyframe is assembled, and the model's
    joints, actuators and rotor armature are as documented."""
    design = Design(L0=0.3, L1=0.25, L2=0.45)
    inertia = Inertia.default(design)
    model = mujoco.MjModel.from_xml_string(to_mjcf(design, inertia, torque_limits=(5, 6, 7)))
    data = mujoco.MjData(model)
    assert [model.joint(i).name for i in range(model.njnt)] == list(JOINT_NAMES)
    assert model.nu == 3 and model.neq == 1
    np.testing.assert_allclose(model.actuator_ctrlrange[:, 1], [5, 6, 7])
    np.testing.assert_allclose(model.dof_armature[[0, 1, 3]], inertia.rotor)
    for mode in ("+", "-"):
        q = random_postures(design, mode, 20, seed=1)
        p = forward_batch(design, q, mode).p
        for qp, pp in zip(mjcf_qpos(design, q, mode), p, strict=True):
            data.qpos[:] = qp
            mujoco.mj_kinematics(model, data)
            np.testing.assert_allclose(data.site("tip_C").xpos, pp, atol=1e-12)
            np.testing.assert_allclose(data.site("tip_D").xpos, pp, atol=1e-12)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_kinematics(model, data)
    assert np.linalg.norm(data.site("tip_C").xpos - data.site("tip_D").xpos) < 1e-12


def test_every_inertia_the_model_accepts_loads_in_mujoco() -> None:
    """At the triangle bound the model accepts (``I_axial`` = 2 ``I_perp``, and its 1e-12
    slack above), for random moments, MuJoCo loads the export: its check ``A + B >= C`` is
    exact, and 12 written digits broke it in 13 of 40 such values. The moments read back
    are the model's to 1e-12 (relative)."""
    design = Design(L0=0.3, L1=0.25, L2=0.45)
    rng = np.random.default_rng(7)
    for k in range(40):
        ip = float(10 ** rng.uniform(-6, 0))
        ia = 2 * ip * (1 + 1e-12) if k % 2 else 2 * ip
        link = LinkInertia(float(rng.uniform(0.05, 2)), float(rng.uniform(0, 1)), ip, ia)
        inertia = Inertia(
            proximal=link,
            distal=link,
            payload_mass=0.5,
            base_inertia=0.01,
            rotor=(0.001, 0.001, 0.001),
        )
        model = mujoco.MjModel.from_xml_string(to_mjcf(design, inertia))
        moments = np.sort(model.body_inertia[1:], axis=1)
        hit = np.isclose(moments[:, 0], ip, rtol=1e-12) & np.isclose(moments[:, 2], ia, rtol=1e-11)
        assert hit.sum() >= 4, (k, ip, ia)  # the four link bodies


def test_mujoco_simulation_under_the_products_torques_follows_the_motion() -> None:
    """Simulate the export for 0.2 s (RK4, dt 1e-4) driven by the product's torques of a
    smooth motion: the actuated joints follow it to 1e-6 rad (measured 2e-8 rad, limited by
    the constraint's softness and the torques held over each step); torques 1 % off move the
    joints by 8e-3 rad."""
    design = Design.default()
    inertia = Inertia.default(design)
    model = mujoco.MjModel.from_xml_string(to_mjcf(design, inertia, gravity=GRAVITY))
    data = mujoco.MjData(model)
    q0 = np.array([0.3, 2.0, 1.0])
    amp, om = np.array([0.3, -0.2, 0.25]), np.array([5.0, 7.0, 6.0])

    def motion(t: float):
        return (q0 + amp * np.sin(om * t), amp * om * np.cos(om * t), -amp * om**2 * np.sin(om * t))

    q, qd, _ = motion(0.0)
    data.qpos[:] = mjcf_qpos(design, q[None], "+")[0]
    dofs = [int(model.joint(name).dofadr[0]) for name in JOINT_NAMES]
    pas = [dofs[2], dofs[4]]
    j = _loop_jacobian(model, data, data.qpos.copy())
    s = np.zeros((model.nv, 3))
    s[[dofs[0], dofs[1], dofs[3]]] = np.eye(3)
    s[pas] = -np.linalg.pinv(j[:, pas]) @ j[:, [dofs[0], dofs[1], dofs[3]]]
    data.qvel[:] = s @ qd
    worst = 0.0
    steps = round(0.2 / model.opt.timestep)
    for k in range(steps):
        t = k * model.opt.timestep
        # torques held over the RK4 step at its midpoint value
        qm, qdm, qddm = motion(t + model.opt.timestep / 2)
        data.ctrl[:] = inverse_dynamics(design, inertia, qm, qdm, qddm, gravity=GRAVITY).tau[0]
        mujoco.mj_step(model, data)
        q_ref = motion(t + model.opt.timestep)[0]
        worst = max(worst, float(np.max(np.abs(data.qpos[[0, 1, 3]] - q_ref))))
    assert worst < 1e-6


INERTIA_WIRE = {
    "proximal": {"mass": 0.7, "com": 0.3, "I_perp": 0.004, "I_axial": 0.0075},
    "distal": {"mass": 1.1, "com": 0.65, "I_perp": 0.02, "I_axial": 0.001},
    "payload": {"mass": 0.8},
    "base": {"inertia": 0.03},
    "rotor": [0.002, 0.001, 0.003],
}


def _closes_on_p(xml: str, design: Design, home: np.ndarray, mode: str):
    """Load the XML in MuJoCo; at the keyframe both tips sit on the product's P (1e-12 m)."""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_kinematics(model, data)
    p = forward_batch(design, home, mode).p[0]
    np.testing.assert_allclose(data.site("tip_C").xpos, p, atol=1e-12)
    np.testing.assert_allclose(data.site("tip_D").xpos, p, atol=1e-12)
    return model


def test_design_mjcf_endpoints_load_in_mujoco(api) -> None:
    """POST /v1/design/mjcf (design with inertia, gravity, home) and GET (lengths in the
    query): application/xml that MuJoCo loads, the loop closed on the product's P at the
    keyframe, the request's masses, rotors and gravity in the model; the client's
    design_mjcf is the POST."""
    body = {
        "design": {"L0": 0.3, "L1": 0.25, "L2": 0.45, "inertia": INERTIA_WIRE},
        "gravity": list(GRAVITY),
        "assembly_mode": "-",
        "home": [0.4, 2.2, 0.8],
    }
    r = api.post("/v1/design/mjcf", json=body)
    assert r.status_code == 200, r.text
    assert r.headers["content-type"].startswith("application/xml")
    design = Design(L0=0.3, L1=0.25, L2=0.45)
    model = _closes_on_p(r.text, design, np.array([0.4, 2.2, 0.8]), "-")
    np.testing.assert_allclose(model.opt.gravity, GRAVITY)
    np.testing.assert_allclose(model.body("proximal_C").mass, 0.7)
    np.testing.assert_allclose(model.body("distal_C").mass, 1.1)
    np.testing.assert_allclose(model.dof_armature[[0, 1, 3]], [0.002, 0.001, 0.003])
    assert r.text == to_mjcf(design, ODD, gravity=GRAVITY, home=(0.4, 2.2, 0.8), assembly_mode="-")
    g = api.get("/v1/design/mjcf", params={"L0": 0.3, "L1": 0.25, "L2": 0.45})
    assert g.status_code == 200 and g.headers["content-type"].startswith("application/xml")
    model = _closes_on_p(g.text, design, np.array([0.0, 2.0, 1.0]), "+")
    assert g.text == to_mjcf(design)  # default inertia, gravity and keyframe
    import httpx

    from planner.client import PlannerClient

    def forward(request: httpx.Request) -> httpx.Response:
        out = api.request(
            request.method,
            request.url.path,
            content=request.content,
            headers={"content-type": "application/json"},
        )
        return httpx.Response(out.status_code, content=out.content, headers=out.headers)

    with PlannerClient("http://x", transport=httpx.MockTransport(forward)) as client:
        xml = client.design_mjcf(
            body["design"], assembly_mode="-", gravity=GRAVITY, home=[0.4, 2.2, 0.8]
        )
    assert xml.decode() == r.text


@pytest.mark.parametrize(
    ("method", "change", "loc"),
    [
        ("get", {"L1": -1}, ["query", "L1"]),
        ("get", {"L2": "abc"}, ["query", "L2"]),
        ("get", {"colour": "red"}, ["query", "colour"]),
        ("post", {"design": {"L1": 0}}, ["body", "design", "L1"]),
        ("post", {"design": {"inertia": {"proximal": {"mass": 1, "com": 1.5, "I_perp": 0.1,
                                                      "I_axial": 0.1}}}},
         ["body", "design", "inertia", "proximal", "com"]),
        ("post", {"home": [0.0, 3.14159, 0.0], "design": {"L2": 0.3}}, ["body", "home"]),
        ("post", {"gravity": [0, 0, "x"]}, ["body", "gravity", 2]),
    ],
)  # fmt: skip
def test_design_mjcf_bad_input_is_a_422_at_the_field(api, method, change, loc) -> None:
    if method == "get":
        r = api.get("/v1/design/mjcf", params=change)
    else:
        r = api.post("/v1/design/mjcf", json=change)
    assert r.status_code == 422, r.text
    assert r.json()["detail"][0]["loc"] == loc


@pytest.mark.parametrize("L2", [0.26, 0.2])
def test_a_query_design_the_default_home_does_not_assemble_gets_a_nearby_keyframe(api, L2):
    """``GET /v1/design/mjcf`` takes no ``home``: a design whose links do not assemble at
    the default keyframe gets the posture nearest to it that does (a 422 at ``query.home``
    named a parameter the route does not have); MuJoCo loads the model at that keyframe
    with the loop closed."""
    r = api.get("/v1/design/mjcf", params={"L2": L2})
    assert r.status_code == 200, r.text
    model = mujoco.MjModel.from_xml_string(r.text)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    design = Design(0.5, 0.2, L2)  # the default robot's L0, L1
    q = data.qpos[[0, 1, 3]]
    assert np.allclose(mjcf_qpos(design, q[None])[0], data.qpos, atol=1e-9)
    tips = [data.site_xpos[i] for i in range(model.nsite)]
    assert np.allclose(tips[0], tips[1], atol=1e-9)  # the loop closed at P


def test_a_design_that_never_assembles_names_the_design_not_home(api):
    far = {"L0": 2.0, "L1": 0.2, "L2": 0.2}  # |CD| >= L0 - 2 L1 > 2 L2 in every posture
    r = api.get("/v1/design/mjcf", params=far)
    assert r.status_code == 422, r.text
    (item,) = r.json()["detail"]
    assert item["loc"] == ["query"] and "assembles in no posture" in item["msg"], item
    r = api.post("/v1/design/mjcf", json={"design": far})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body"], r.text
