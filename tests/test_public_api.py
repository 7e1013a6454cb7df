"""The public surface: every name in __all__ resolves and is documented; import stays light."""

from __future__ import annotations

import inspect
import subprocess
import sys

import pytest

import rockscan


@pytest.mark.parametrize("name", [n for n in rockscan.__all__ if n != "__version__"])
def test_public_names_resolve_and_are_documented(name):
    obj = getattr(rockscan, name)
    # A public name must never be shadowed by a submodule of the same name.
    assert not inspect.ismodule(obj), f"rockscan.{name} is a module"
    doc = inspect.getdoc(obj) or ""
    assert len(doc) > 20, f"{name} needs a docstring"
    if inspect.isfunction(obj) and obj.__module__.startswith("rockscan"):
        params = [p for p in inspect.signature(obj).parameters if p not in ("self", "cls")]
        if params:
            assert "Parameters" in doc or "See :func:" in doc, f"{name}: document its parameters"


def test_unknown_name():
    with pytest.raises(AttributeError, match="no attribute 'moon'"):
        rockscan.moon  # noqa: B018


def test_importing_the_package_and_cli_stays_light():
    # `rockscan --help` must start at once: no numpy, scipy, OpenCV or skimage.
    code = (
        "import sys, rockscan, rockscan.cli; "
        "heavy = [m for m in ('numpy', 'scipy', 'cv2', 'skimage', 'matplotlib') if m in sys.modules]; "
        "print(','.join(heavy))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


def test_stage_modules_are_reachable_and_their_functions_too():
    import importlib

    assert rockscan.core.segment.segment is importlib.import_module("rockscan.core.segment").segment
    assert callable(rockscan.core.superformula.superformula)
    # Importing a stage does not shadow the public names.
    importlib.import_module("rockscan.run.pipeline")
    assert not inspect.ismodule(rockscan.classify_image)


@pytest.mark.parametrize(
    "call",
    [
        lambda photo, out: rockscan.classify_path(photo, "default"),
        lambda photo, out: rockscan.classify_image(rockscan.read_image(photo).pixels, "default"),
        lambda photo, out: rockscan.match_radii([1.0] * 360, "default"),
        lambda photo, out: rockscan.rotation_scores([1.0] * 360, None),
        lambda photo, out: rockscan.save_library("default", out / "lib.npz"),
        lambda photo, out: rockscan.triage_folder(photo.parent, out / "r.jsonl", "default"),
    ],
)
def test_a_library_name_where_a_library_goes_is_a_type_error_that_says_how(call, tmp_path):
    # The command line takes "default"; the functions take the library, and a name
    # failed deep inside with an AttributeError on a string.
    photo = tmp_path / "photos" / "star.png"
    photo.parent.mkdir()
    photo.write_bytes(rockscan.render_photo(rockscan.SuperformulaParams(5, 5, 2, 7, 7), rng=0).encode(".png"))
    with pytest.raises(TypeError, match=r"library must be a Library \(rockscan.default_library\(\)"):
        call(photo, tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["photos"]


def test_a_shape_name_where_a_shape_goes_is_a_type_error():
    with pytest.raises(TypeError, match="not the name 'tri'; read_spec"):
        rockscan.render_photo("tri")
    with pytest.raises(rockscan.ParameterError, match="radii must be numbers"):
        rockscan.render_photo([1.0, "a"] * 8)
