"""Package list for setuptools (everything else is in pyproject.toml).

The pillars ``ident/``, ``excitation/`` and ``drivers/`` live at the top of the
repository but install as ``servoid.ident`` and so on (``package-dir`` in
pyproject.toml). ``find_packages`` cannot rename, so the list is built here:
a subpackage added under any pillar is picked up without editing a list.
"""

from setuptools import find_packages, setup

PILLARS = ("ident", "excitation", "drivers")

packages = ["servoid"] + [f"servoid.{p}" for p in find_packages("servoid")]
for pillar in PILLARS:
    packages.append(f"servoid.{pillar}")
    packages += [f"servoid.{pillar}.{p}" for p in find_packages(pillar)]

setup(packages=packages)
