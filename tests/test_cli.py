"""Tests of the command line: ``pickplace inspect --json``, ``--export-xml`` and ``--version``."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import mujoco
import pytest

from pickplace import __version__
from pickplace.cli import main
from pickplace.robot import model


def test_inspect_json(capsys) -> None:
    """``pickplace inspect --json`` in-process (it runs the IK and the hold margin), stdout parsed as JSON."""
    code = main(["inspect", "--json"])
    out = capsys.readouterr().out
    assert code == 0
    data = json.loads(out)
    assert set(data) >= {"version", "model", "gripper", "ik", "hold"}
    assert data["version"] == __version__
    _check_ik(data)
    _check_hold(data)
    _check_gripper_and_model(data)


def _check_ik(inspect_json: dict) -> None:
    ik = inspect_json["ik"]
    assert [r["name"] for r in ik] == ["pregrasp", "grasp", "lift", "preplace", "place", "retreat"]
    for r in ik:
        assert r["position_error_m"] < 1e-4, r["name"]
        assert r["orientation_error_rad"] < 1e-4, r["name"]
        assert len(r["q_rad"]) == 6


def _check_hold(inspect_json: dict) -> None:
    hold = inspect_json["hold"]
    print(f"\ninspect hold: slip {hold['slip_m'] * 1e3:.4f} mm, grip {hold['grip_force_n']:.2f} N per pad, "
          f"peak {hold['peak_acceleration_m_s2']:.2f} m/s^2, safety factor {hold['safety_factor']}, trials "
          + ", ".join(f"{t['mass_kg']:.3g} kg {'held' if t['held'] else 'LOST'}" for t in hold["trials"]))
    assert hold["held"] is True
    assert hold["slip_m"] < 0.001
    assert hold["safety_factor"] >= 3
    assert hold["peak_acceleration_m_s2"] >= 3.0
    assert hold["trials"][0]["mass_kg"] == pytest.approx(0.150, abs=1e-12)
    # the safety factor at the lowest friction of the default randomization as well as at the scene's
    by_mu = {m["friction"]: m for m in hold["by_friction"]}
    assert set(by_mu) == {0.6, 1.0}
    assert by_mu[1.0]["safety_factor"] == hold["safety_factor"]
    assert by_mu[0.6]["safety_factor"] >= 8 and by_mu[1.0]["safety_factor"] >= 16
    for m in by_mu.values():
        print(f"mu {m['friction']}: safety factor {m['safety_factor']}, heaviest held "
              f"{m['heaviest_held_kg']:.2f} kg, Coulomb limit {m['coulomb_limit_kg']:.2f} kg")
        lost = [t["mass_kg"] for t in m["trials"] if not t["held"]]
        assert m["heaviest_held_kg"] >= 0.6 * m["coulomb_limit_kg"]  # it holds what friction allows
        assert not lost or lost[0] >= 0.9 * m["coulomb_limit_kg"]  # and loses nothing friction could carry


def _check_gripper_and_model(inspect_json: dict) -> None:
    g = inspect_json["gripper"]
    assert "closed_inner_face_y_m" in g
    assert "open_width_m" in g
    assert g["closed_inner_face_y_m"] < g["object_half_width_m"]
    assert g["open_width_m"] > 2 * g["object_half_width_m"] + 0.010
    mdl = inspect_json["model"]
    assert mdl["timestep_s"] == pytest.approx(0.001, abs=1e-15)
    assert [j["name"] for j in mdl["joints"]] == list(model.ARM_JOINTS)
    assert [j["torque_limit_nm"] for j in mdl["joints"]] == [150.0, 150.0, 150.0, 28.0, 28.0, 28.0]
    assert mdl["pinocchio_joints"] == [*model.ARM_JOINTS, "left_finger_joint", "right_finger_joint"]


def test_export_xml_compiles(tmp_path, capsys) -> None:
    path = tmp_path / "scene.xml"
    assert main(["inspect", "--export-xml", str(path)]) == 0
    assert "wrote" in capsys.readouterr().out
    assert path.exists()
    m = mujoco.MjModel.from_xml_path(str(path))
    reference = model.build().mj
    assert m.nq == reference.nq
    assert m.nv == reference.nv
    assert m.nu == reference.nu
    assert m.nbody == reference.nbody


def test_version_subprocess() -> None:
    proc = subprocess.run([sys.executable, "-m", "pickplace", "--version"], capture_output=True, text=True,
                          timeout=60, check=False)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == f"pickplace {__version__}"


def test_run_viewer_without_a_display_says_so() -> None:
    """``--viewer`` on a headless machine: one clear line pointing to ``--video``, before anything runs."""
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    proc = subprocess.run([sys.executable, "-m", "pickplace", "run", "--viewer"], capture_output=True, text=True,
                          timeout=120, env=env)
    if sys.platform in ("darwin", "win32"):
        pytest.skip("those platforms always have a display")
    assert proc.returncode == 1
    assert proc.stdout == "" and "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "--viewer needs a display" in lines[0] and "--video" in lines[0]


def test_objects_json_lists_each_object_with_its_feasible_grasps(capsys) -> None:
    assert main(["objects", "--json", "cube", "soda_can_lying"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert [d["name"] for d in data] == ["cube", "soda_can_lying"]
    for d in data:
        assert 0 < d["feasible"] <= d["grasps_at_default_pose"] <= d["grasps"]
        assert sum(d["feasible_by_approach"].values()) == d["feasible"]
        assert d["mass_kg"] > 0 and d["source"]
    assert data[0]["extent_m"] == pytest.approx([0.04, 0.04, 0.04], abs=1e-12)
    assert main(["objects", "teapot"]) == 1
    assert "objects = 'teapot' is invalid" in capsys.readouterr().err


def _mesh_error(capsys, path: str) -> str:
    assert main(["run", "--object-mesh", path, "--object-mass", "0.2"]) == 1
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines  # one clear line
    return lines[0]


def test_user_mesh_errors_are_one_line_each(tmp_path, capsys) -> None:
    import trimesh

    assert "no such file" in _mesh_error(capsys, str(tmp_path / "missing.stl"))
    trimesh.creation.box((0.2, 0.2, 0.2)).export(tmp_path / "big.stl")
    assert "too large for the gripper" in _mesh_error(capsys, str(tmp_path / "big.stl"))
    open_box = trimesh.creation.box((0.04, 0.04, 0.04))
    open_box.faces = open_box.faces[:-2]
    open_box.export(tmp_path / "open.stl")
    assert "not watertight" in _mesh_error(capsys, str(tmp_path / "open.stl"))


def test_user_mesh_runs_end_to_end(tmp_path, capsys) -> None:
    import trimesh

    trimesh.creation.cylinder(radius=0.025, height=0.08, sections=48).export(tmp_path / "can.stl")
    assert main(["run", "--object-mesh", str(tmp_path / "can.stl"), "--object-mass", "0.2", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["success"] and result["config"]["object"]["kind"] == "mesh"
    assert result["place_error_xy_m"] < 0.001


def test_run_task_json_and_its_usage_errors(capsys) -> None:
    assert main(["run", "--task", "stack", "--objects", "2", "--seed", "3", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["success"] and out["kind"] == "stack" and len(out["objects"]) == 2
    assert [label for _, label in out["order"]] == ["level 1", "level 2"]
    assert main(["run", "--objects", "2"]) == 1
    assert "--objects and --order go with --task" in capsys.readouterr().err
    assert main(["run", "--task", "place", "--objects", "9"]) == 1
    assert "--objects" in capsys.readouterr().err
