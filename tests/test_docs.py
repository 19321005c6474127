"""Documentation that is generated from code stays in sync with it."""

from viz3d.scene import format_reference

from conftest import ROOT


def test_scene_format_reference_is_current():
    text = (ROOT / "docs" / "scene_format.md").read_text()
    block = text.split("```text\n", 1)[1].rsplit("```", 1)[0]
    assert block.strip() == format_reference().strip(), "regenerate with: viz3d list --format"


def test_trajectory_doc_lists_every_saved_field():
    from dataclasses import fields

    from viz3d.trajectory import Trajectory

    text = (ROOT / "docs" / "trajectory.md").read_text()
    missing = [f.name for f in fields(Trajectory) if f"`{f.name}`" not in text]
    assert not missing, missing


def test_readme_commands_of_measured_numbers_are_the_generated_ones():
    """Every `viz3d bench` / `viz3d stability` command the README shows is one that
    benchmarks/docs_charts.py ran to produce docs/charts (so the numbers quoted next to it come
    from that very command)."""
    readme = (ROOT / "README.md").read_text()
    generated = (ROOT / "docs" / "charts" / "README.md").read_text()
    shown = [line.strip() for line in readme.splitlines() if line.strip().startswith(("viz3d bench", "viz3d stability"))]
    assert shown, "the README shows no benchmark command"
    missing = [c for c in shown if f"    {c}\n" not in generated]
    assert not missing, f"not produced by benchmarks/docs_charts.py: {missing}"
