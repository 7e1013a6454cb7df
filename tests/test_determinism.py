"""Results do not depend on BLAS threads, nor on running in or out of process.

rockscan holds BLAS to one thread inside its numeric entry points
(rockscan/core/_threads.py), which makes the JSON of a photo the same bytes at any
``OPENBLAS_NUM_THREADS``; these tests hold it to that guarantee.
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading

import numpy as np
import pytest
from click.testing import CliRunner
from threadpoolctl import threadpool_info, threadpool_limits

from rockscan.cli import main
from rockscan.core import _threads
from rockscan.core.eigen import EigenBasis
from rockscan.core.information import information_face
from rockscan.core.render import RenderConfig, render_photo
from rockscan.core.superformula import shape_radii

pytestmark = pytest.mark.skipif(
    not any(lib["user_api"] == "blas" for lib in threadpool_info()),
    reason="no BLAS library that threadpoolctl can limit",
)


@pytest.fixture(scope="module")
def photos(tmp_path_factory, default_specs):
    root = tmp_path_factory.mktemp("determinism")
    config = RenderConfig(rows=160, cols=200, area_fraction=0.2)
    paths = []
    for i, spec in enumerate(default_specs[:8]):
        path = root / f"{i:02d}-{spec.name}.png"
        path.write_bytes(render_photo(spec.params, config, rng=[41, i]).encode(".png"))
        paths.append(str(path))
    return paths


def _classify_in_subprocess(paths: list[str], threads: str) -> bytes:
    env = {**os.environ, "OPENBLAS_NUM_THREADS": threads, "OMP_NUM_THREADS": threads}
    code = "import sys; from rockscan.cli import main; sys.exit(main())"
    out = subprocess.run(
        [sys.executable, "-c", code, "classify", "--json", *paths], env=env, capture_output=True, check=True
    )
    return out.stdout


def test_json_lines_are_the_same_bytes_at_one_and_two_blas_threads_and_in_process(photos):
    one = _classify_in_subprocess(photos, "1")
    two = _classify_in_subprocess(photos, "2")
    assert len(one.splitlines()) == len(photos)
    assert one == two
    # In this process numpy is loaded already: the environment no longer counts,
    # only the library's own limit does.
    with threadpool_limits(2, user_api="blas"):
        result = CliRunner().invoke(main, ["classify", "--json", *photos])
    assert result.exit_code == 0, result.output
    assert result.stdout_bytes == one


def _library_faces(default_specs):
    radii = np.array([shape_radii(s.params, 360) for s in default_specs])
    return information_face(radii)


def test_the_eigenface_fit_is_the_same_at_any_thread_count(default_specs):
    faces = _library_faces(default_specs)
    fits = []
    for threads in (1, 2, 4):
        with threadpool_limits(threads, user_api="blas"):
            fits.append(EigenBasis.from_faces(faces))
    for fit in fits[1:]:
        for name in ("mean", "components", "eigenvalues", "weights"):
            np.testing.assert_array_equal(getattr(fit, name), getattr(fits[0], name))


def test_the_limit_holds_inside_and_gives_the_users_setting_back():
    seen = []
    limited = _threads.one_blas_thread(lambda: seen.append(_threads.blas_threads()))
    nested = _threads.one_blas_thread(lambda: (limited(), seen.append(_threads.blas_threads())))
    with threadpool_limits(3, user_api="blas"):
        nested()
        assert seen == [1, 1]
        assert _threads.blas_threads() == 3


def test_concurrent_calls_share_one_limit_until_the_last_leaves():
    inside, release, seen = threading.Barrier(3), threading.Event(), []

    def hold() -> None:
        inside.wait()
        release.wait()
        seen.append(_threads.blas_threads())

    held = _threads.one_blas_thread(hold)
    with threadpool_limits(2, user_api="blas"):
        workers = [threading.Thread(target=held) for _ in range(2)]
        for worker in workers:
            worker.start()
        inside.wait()  # both are inside
        release.set()
        for worker in workers:
            worker.join()
        assert seen == [1, 1]
        assert _threads.blas_threads() == 2
