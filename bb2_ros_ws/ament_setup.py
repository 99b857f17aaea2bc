"""The ``setup()`` of every ament_python package of this workspace, from its ``package.xml``.

Each ``src/<pkg>/setup.py`` calls :func:`setup_package` with what is its own (its executables, the folders it
installs into ``share/<pkg>``); the name, version, description, maintainer and license come from the package's
``package.xml``, the one manifest ROS reads, so the two never disagree.  The rest is the ament_python convention:
the package marker in the ament index, ``package.xml`` in ``share/<pkg>``, the Python package (``src/<pkg>/<pkg>``,
a symlink to the top-level source) with its data files, executables under ``lib/<pkg>`` (``setup.cfg``).

Called the way colcon, pip and ``bb2_ros_ws/install_into_venv.py`` run a ``setup.py``: from the package's
directory (or, for ``colcon build --symlink-install``, its build directory of symlinks); ``setuptools.setup`` is
looked up at call time, so a reader that patches it (colcon's, ours) sees the arguments.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Mapping, Sequence

import setuptools

PACKAGE_DATA = ['data/*.json', 'data/*.yaml', 'data/**/*.json', 'data/**/*.yaml', 'data/**/*.npz']
"""The data files a Python package of this workspace carries (coefficients, tunings, tables)."""


def manifest(package_xml: Path) -> dict[str, str]:
    """``name``, ``version``, ``description``, ``maintainer``, ``maintainer_email`` and ``license`` of a
    ``package.xml`` (format 3)."""
    root = ET.parse(package_xml).getroot()
    maintainer = root.find('maintainer')
    if maintainer is None:
        raise ValueError(f'{package_xml}: no <maintainer>')
    return {'name': root.findtext('name', '').strip(), 'version': root.findtext('version', '').strip(),
            'description': ' '.join(root.findtext('description', '').split()),
            'maintainer': (maintainer.text or '').strip(), 'maintainer_email': maintainer.get('email', ''),
            'license': root.findtext('license', '').strip()}


def setup_package(setup_py: str, *, console_scripts: Sequence[str] = (),
                  share: Mapping[str, Sequence[str]] | None = None, python: bool = True) -> None:
    """``setuptools.setup()`` of the package whose ``setup.py`` is ``setup_py`` (its ``__file__``).

    ``console_scripts``: ``'executable = module:function'`` entries; ``share``: ``{subfolder: [glob, ...]}`` of
    files installed into ``share/<pkg>/<subfolder>`` (globs relative to the package directory); ``python``:
    whether the package holds a Python package of its name (``bb2_bringup`` holds none).
    """
    pkg_dir = Path(setup_py).resolve().parent  # the source directory, also from a build directory of symlinks
    meta = manifest(pkg_dir / 'package.xml')
    name = meta['name']
    data_files = [('share/ament_index/resource_index/packages', ['resource/' + name]),
                  ('share/' + name, ['package.xml'])]
    for sub, patterns in (share or {}).items():
        files = sorted({str(p.relative_to(pkg_dir)) for pattern in patterns for p in pkg_dir.glob(pattern)})
        if not files:
            raise FileNotFoundError(f'{pkg_dir}: nothing matches {list(patterns)} for share/{name}/{sub}')
        data_files.append((f'share/{name}/{sub}', files))
    setuptools.setup(
        **meta,
        packages=setuptools.find_packages(include=[name, name + '.*']) if python else [],
        package_data={name: PACKAGE_DATA} if python else {},
        data_files=data_files,
        install_requires=['setuptools'],
        zip_safe=False,
        entry_points={'console_scripts': list(console_scripts)},
    )
