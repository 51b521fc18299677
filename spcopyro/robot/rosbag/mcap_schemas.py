"""The one place spcopyro reaches into rosbags' internals: an mcap schema without data read as
"no definition" while a ROS 2 bag opens.

rosbag2 records a type whose definition it cannot find with ``encoding: unknown`` and empty
data (rosbag2_cpp ``LocalMessageDefinitionSource::get_full_text``, ``Format::UNKNOWN``); the MCAP
specification also allows an empty encoding. rosbags (0.11) maps an mcap schema's encoding
through a fixed table (``ros2msg``, ``ros2idl``, ``omgidl`` and ``""`` only:
``rosbags.rosbag2.storage_mcap.get_msgdef``) and fails on such a bag with ``KeyError:
'unknown'``, or parses empty ``ros2msg`` data as a type without fields -- even when
``AnyReader`` is given a ``default_typestore``.

rosbags offers no public way around it (0.11.9: ``AnyReader`` takes only ``default_typestore``,
used when *no* connection has a definition; the schemas are read inside ``McapReader.open``,
before a caller sees the connections), so :func:`schemas_without_data_as_none` wraps that
module function for the call that opens the bag only (not thread-safe against another thread
opening an mcap bag meanwhile). Should a rosbags release drop or move it, opening a ROS 2 bag
raises :class:`RosbagsInternalsError` naming the installed version, rather than silently
failing on such bags again.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

__all__ = ["RosbagsInternalsError", "schemas_without_data_as_none"]


class RosbagsInternalsError(RuntimeError):
    """The installed rosbags lacks the internal function spcopyro wraps to read mcap schemas
    without data (:func:`schemas_without_data_as_none`)."""


def _rosbags_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("rosbags")
    except PackageNotFoundError:
        return "unknown"


@contextmanager
def schemas_without_data_as_none(ros2: bool = True) -> Iterator[None]:
    """While the block runs (a ROS 2 bag opening): an mcap schema with no data is read as
    "no definition", whatever its encoding, so that the ``--ros-distro`` typestore serves its
    type. ``ros2`` False (a ROS 1 bag, which has no mcap schemas): nothing is wrapped.

    Raises:
        RosbagsInternalsError: ``rosbags.rosbag2.storage_mcap.get_msgdef`` is gone (a rosbags
            release spcopyro was not adapted to), naming the installed rosbags version.
    """
    if not ros2:
        yield
        return
    try:
        from rosbags.rosbag2 import storage_mcap

        original = storage_mcap.get_msgdef
    except (ImportError, AttributeError) as error:
        raise RosbagsInternalsError(
            f"rosbags {_rosbags_version()} has no rosbags.rosbag2.storage_mcap.get_msgdef "
            f"({type(error).__name__}: {error}), which spcopyro wraps to read ROS 2 mcap bags "
            "that store no message definitions (tested with rosbags 0.11): install "
            '"rosbags>=0.11,<0.12" or report it to spcopyro'
        ) from None

    def get_msgdef(schema: Any) -> Any:
        return original(None if schema is not None and not schema.data else schema)

    storage_mcap.get_msgdef = get_msgdef
    try:
        yield
    finally:
        storage_mcap.get_msgdef = original
