"""Robot recordings (rosbags) in and out: ``spcopyro import-bag`` and ``spcopyro simulate-bag``.

* :mod:`~spcopyro.robot.rosbag.poses`: planar pose tracks, interpolation at a stamp, tf composition.
* :mod:`~spcopyro.robot.rosbag.bag`: reading a ROS 1 or ROS 2 bag (rosbags' AnyReader): topics,
  poses, image stamps, utterances; clear errors for what is missing or malformed.
* :mod:`~spcopyro.robot.rosbag.tf_chain`: the bag's tf tree: the chain between two frames
  (``--pose-tf``), a pose topic in another frame placed on the map through it.
* :mod:`~spcopyro.robot.rosbag.mcap_schemas`: the one wrap of rosbags' internals (mcap schemas
  without a definition), failing loudly on a rosbags release without it.
* :mod:`~spcopyro.robot.rosbag.images`: the file to store for an image message.
* :mod:`~spcopyro.robot.rosbag.house_folder`: the house folder and what ``--overwrite`` may replace.
* :mod:`~spcopyro.robot.rosbag.importer`: :func:`import_bags`, bags -> a house folder of the dataset
  layout (``fit`` reads it once ``features`` has written Ft.csv).
* :mod:`~spcopyro.robot.rosbag.report`: what an import reports: :class:`BagImportReport`, the
  skipped observations and ``skipped.csv``.
* :mod:`~spcopyro.robot.rosbag.synthetic`: :class:`BagWriter` and :func:`write_synthetic_bags` (the
  synthetic house recorded as bags).
* :mod:`~spcopyro.robot.rosbag.cli`: the two commands.

``rosbags`` and ``rosbags-image`` are optional (``pip install "spcopyro[ros]"``): nothing here
imports them until a bag is read or written, and ``import spcopyro`` never does.

The names below are imported on first use (PEP 562): the parser imports
:mod:`~spcopyro.robot.rosbag.cli` on every command, and this package's ``__init__`` runs first,
so it must not load :mod:`~spcopyro.robot.rosbag.importer` and
:mod:`~spcopyro.robot.rosbag.synthetic` (~0.02 s) for ``spcopyro --help``
(``tests/test_cli_startup.py``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from spcopyro._util.lazy import lazy_names

if TYPE_CHECKING:
    from spcopyro.robot.rosbag.bag import BagContentError, BagFormatError, RosbagsMissingError
    from spcopyro.robot.rosbag.importer import (
        ImportOptions,
        NothingLeftError,
        PoseOutsideMapError,
        import_bags,
    )
    from spcopyro.robot.rosbag.report import BagImportReport, SkippedObservation
    from spcopyro.robot.rosbag.synthetic import BagWriter, write_synthetic_bags

_HOMES = {
    "BagContentError": "bag",
    "BagFormatError": "bag",
    "BagImportReport": "report",
    "BagWriter": "synthetic",
    "ImportOptions": "importer",
    "NothingLeftError": "importer",
    "PoseOutsideMapError": "importer",
    "RosbagsMissingError": "bag",
    "SkippedObservation": "report",
    "import_bags": "importer",
    "write_synthetic_bags": "synthetic",
}
"""Each public name and the module (of this package) that defines it."""

__all__ = [
    "BagContentError",
    "BagFormatError",
    "BagImportReport",
    "BagWriter",
    "ImportOptions",
    "NothingLeftError",
    "PoseOutsideMapError",
    "RosbagsMissingError",
    "SkippedObservation",
    "import_bags",
    "write_synthetic_bags",
]


__getattr__, __dir__ = lazy_names(__name__, _HOMES)
