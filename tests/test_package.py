"""Packaging: what a non-editable install needs (CI installs it that way)."""

from __future__ import annotations

from conftest import REPO

from kinectdata.core.resources import schemas_dir, shipped_names


def test_every_folder_of_python_modules_is_a_package():
    for folder in (REPO / "kinectdata").rglob("*"):
        if folder.is_dir() and any(folder.glob("*.py")):
            assert (folder / "__init__.py").is_file(), f"{folder} has modules but no __init__.py"


def test_schema_files_are_found_through_the_package():
    assert (schemas_dir() / "csv-schema.schema.json").is_file()
    assert {"jointsets", "csv", "targets"} <= {p.name for p in schemas_dir().iterdir() if p.is_dir()}
    assert "yalta65" in shipped_names("targets") and "kinect_v2" in shipped_names("jointsets")


def test_the_report_templates_are_found_through_the_package():
    from importlib import resources

    templates = resources.files("kinectdata.viz") / "templates"
    assert {"report.html.j2", "report_parts.html.j2"} <= {p.name for p in templates.iterdir()}
    assert (schemas_dir() / "shard-json-attributes.schema.json").is_file()


def test_every_data_file_of_the_checkout_is_installed():
    """Each schema, joint set, mapping and template in the checkout is found through the installed
    package (a package-data pattern that misses a nested folder ships nothing from it)."""
    from importlib import resources

    checkout = REPO / "kinectdata"
    installed = resources.files("kinectdata")
    wanted = [p.relative_to(checkout) for p in checkout.rglob("*") if p.suffix in (".json", ".j2")]
    assert wanted
    missing = [str(p) for p in wanted if not installed.joinpath(*p.parts).is_file()]
    assert not missing, f"not installed: {missing}"


def test_a_stale_install_of_the_package_is_named_before_the_tests_run(tmp_path):
    from conftest import stale_install

    source, installed = tmp_path / "checkout" / "kinectdata", tmp_path / "site" / "kinectdata"
    for folder in (source, installed):
        (folder / "targets").mkdir(parents=True)
        (folder / "__init__.py").write_text("x = 1\n")
        (folder / "targets" / "travel.py").write_text("y = 2\n")
    assert stale_install(installed, source) == ""  # an install of the same code (CI's)
    assert stale_install(source, source) == ""  # the checkout itself (an editable install)
    (source / "targets" / "sway.py").write_text("z = 3\n")
    said = stale_install(installed, source)
    assert f"from {installed}, which lacks this checkout's kinectdata/targets/sway.py" in said
    assert said.endswith("install it again (pip install -e .)")
    (installed / "targets" / "sway.py").write_text("z = 3\n")
    (source / "__init__.py").write_text("x = 2\n")
    assert "whose kinectdata/__init__.py is not this checkout's" in stale_install(installed, source)
