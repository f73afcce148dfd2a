"""The package's version is ellroll's, set once in ../CMakeLists.txt."""
import pathlib
import re

from setuptools import setup

cmake = (pathlib.Path(__file__).resolve().parent.parent / "CMakeLists.txt").read_text()
setup(version=re.search(r"project\(ellroll VERSION ([0-9.]+)", cmake).group(1))
