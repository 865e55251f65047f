"""Builds the Python package's extension module with the project's CMake build (metadata: pyproject.toml).

By default CMake configures a build of the library and the module alone under setuptools' build_temp.
FACETREE_CMAKE_BUILD_DIR names an existing build configured with -DFACETREE_PYTHON=ON to reuse
instead (only the module's target is built there), as scripts/test does.
"""
import os
import shutil
import subprocess
import sys
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = Path(__file__).resolve().parent


class CMakeExtension(Extension):
    def __init__(self, name: str) -> None:
        super().__init__(name, sources=[])


class CMakeBuild(build_ext):
    def build_extension(self, ext: Extension) -> None:
        given = os.environ.get("FACETREE_CMAKE_BUILD_DIR")
        build_dir = Path(given or Path(self.build_temp) / "cmake").resolve()
        if not given:
            configure = ["cmake", "-S", str(ROOT), "-B", str(build_dir), "-DCMAKE_BUILD_TYPE=Release",
                         "-DFACETREE_PYTHON=ON", "-DFACETREE_BUILD_CLI=OFF",
                         "-DFACETREE_BUILD_TESTS=OFF", "-DFACETREE_BUILD_BENCH=OFF",
                         f"-DPython_EXECUTABLE={sys.executable}"]
            try:  # pybind11 from a package index (an isolated build); Debian's pybind11-dev is found by CMake
                import pybind11
                configure.append(f"-Dpybind11_DIR={pybind11.get_cmake_dir()}")
            except ImportError:
                pass
            if shutil.which("ninja"):
                configure += ["-G", "Ninja"]
            subprocess.run(configure, check=True)
        elif not (build_dir / "CMakeCache.txt").is_file():
            raise RuntimeError(f"FACETREE_CMAKE_BUILD_DIR={given} is not a configured CMake build")
        jobs = str(self.parallel or os.cpu_count() or 1)
        subprocess.run(["cmake", "--build", str(build_dir), "--target", "_facetree", "-j", jobs], check=True)
        target = Path(self.get_ext_fullpath(ext.name))
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(build_dir / "python" / "facetree" / target.name, target)


setup(ext_modules=[CMakeExtension("facetree._facetree")], cmdclass={"build_ext": CMakeBuild})
