"""The candidate effect files and the refitted parameters the identification benchmarks share
(ident_false_discovery.py, ident_truth_table.py): the docs' examples and the tests' two laws."""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

FILES = [
    ROOT / "docs" / "examples" / "effect_joint_torque.py",
    ROOT / "docs" / "examples" / "effect_foot_friction.py",
    ROOT / "docs" / "examples" / "effect_normal_force.py",
    ROOT / "tests" / "ident" / "effects" / "slip_weakening.py",
    ROOT / "tests" / "ident" / "effects" / "rotor_spin_down.py",
]
NAMES = ["ground_damping", "flex_stiffness", "flex_damping"]
