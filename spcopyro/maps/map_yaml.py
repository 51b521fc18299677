"""ROS map_server yaml files: parsing and validating one (``read_map_yaml``).

The one reader of a map's yaml for every map loader of the package (:func:`~spcopyro.maps.load_map`,
:func:`~spcopyro.maps.load_filter_mask`, :func:`~spcopyro.maps.load_label_map_server`): it reads
the keys as map_server reads them (yaml-cpp: ``5e-2`` and quoted numbers are numbers, ``'.inf'``
too, ``" 0.05"`` with a blank before it is none, ``010`` is ten, a tab after ``key:`` is a space,
``negate`` may be a yaml-cpp boolean) and refuses, naming the file, the line,
the key and the value, what map_server refuses or what would make the map meaningless. Its
warnings go to the logger ``spcopyro.maps.map_server``, :func:`~spcopyro.maps.load_map`'s.
"""

from __future__ import annotations

import difflib
import functools
import logging
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from spcopyro._util.messages import echo, shown_bytes
from spcopyro._util.number_checks import is_finite_number, is_number, is_positive_number

if TYPE_CHECKING:
    from collections.abc import Callable

logger = logging.getLogger("spcopyro.maps.map_server")  # load_map's logger, as documented there

__all__ = [
    "MAX_YAW_NOISE", "PLAUSIBLE_RESOLUTION", "MapFileNotFoundError", "MapFormatError",
    "read_map_yaml",
]  # fmt: skip

_REQUIRED_KEYS = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh")
_KNOWN_KEYS = (*_REQUIRED_KEYS, "mode")
_MODES = ("trinary", "scale", "raw")

_KEY_MEANINGS = {
    "image": "the map image's path (pgm, png, ...), relative to the yaml's folder or absolute",
    "resolution": "metres per cell (image pixel), e.g. 0.05",
    "origin": "the world pose [x, y, yaw] of the image's lower-left pixel, metres and radians",
    "negate": "0 where white is free (map_saver's maps), 1 where black is",
    "occupied_thresh": "the occupancy p above which a pixel is occupied, e.g. 0.65",
    "free_thresh": "the occupancy p below which a pixel is free, e.g. 0.196",
}
"""What each required key holds, for the error that says it is missing."""

MAX_YAW_NOISE = 1e-6
"""Radians: an origin yaw this small is read as 0 (a quaternion's float noise, as a mapping
package may save it): it turns a cell 1 km from the origin by 1 mm. A larger yaw is refused
(rotated maps are not supported)."""

PLAUSIBLE_RESOLUTION = (1e-3, 2.0)
"""Metres: :func:`load_map` warns of a ``resolution`` outside this range, naming the yaml's line
and the value: a cell wider than 2 m holds a room (a fit's coarse model cells, ``--cell-size``,
may be 1 or 2 m; its map.yaml loads without a word), and a robot's map is usually 0.05 m a cell
(one of 50 or 5 is 0.05 written in millimetres or centimetres)."""


class MapFormatError(ValueError):
    """A map yaml or image is malformed; the message names the file (and the key and value).

    A byte of the yaml that is not UTF-8 shows in the message as ``\\xe9``, not as the stand-in
    it was read as (:func:`~spcopyro._util.messages.shown_bytes`), whichever module raises it."""

    def __init__(self, message: str = "", *args: object) -> None:
        super().__init__(shown_bytes(str(message)), *args)


class MapFileNotFoundError(MapFormatError, FileNotFoundError):
    """A map yaml or the image it names does not exist."""


# ---------------------------------------------------------------------- yaml parsing
@functools.cache
def _map_yaml_loader() -> type:
    """PyYAML's safe loader, also reading ``5e-2`` and ``1E3`` as floats (YAML 1.2, yaml-cpp and
    so map_server do; YAML 1.1 wants a dot, so PyYAML reads them as strings)."""
    import yaml

    loader = type("_MapYamlLoader", (yaml.SafeLoader,), {})
    loader.add_implicit_resolver(
        "tag:yaml.org,2002:float",
        re.compile(r"^[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)[eE][-+]?[0-9]+$"),
        list("-+0123456789."),
    )
    return loader


@dataclass(frozen=True)
class _MapYaml:
    path: Path
    image: Path
    resolution: float
    origin: tuple[float, float, float]
    negate: bool
    occupied_thresh: float
    free_thresh: float
    mode: str
    lines: dict[str, int] = field(default_factory=dict, compare=False)
    """Line of each key in the yaml (1-based)."""
    negate_text: str = field(default="", compare=False)
    """``negate`` as written in the yaml (quotes removed), e.g. ``2`` or ``yes``."""
    mode_text: str = field(default="", compare=False)
    """``mode`` as written where it is not map_server's (``SCALE``, ``Raw``) and the mode it
    looks like is one the caller refuses (``read_map_yaml``'s ``accepts``), else ""."""

    def shown_negate(self) -> str:
        """``negate`` for a message: as written where it says what it reads as (``0``, ``1``,
        ``true``, ``false``), else with its reading, ``2 (true)``, ``0x0 (false)``."""
        reads = "true" if self.negate else "false"
        plain = {"0": "false", "1": "true", "true": "true", "false": "false"}
        if not self.negate_text or plain.get(self.negate_text.lower()) == reads:
            return self.negate_text or str(int(self.negate))
        return f"{self.negate_text} ({reads})"

    def shown_mode(self) -> str:
        """``mode`` for a caller's refusal: ``'scale'``, or as written with what it was taken
        for, ``'SCALE' (taken for 'scale'; map_server refuses it as written)``."""
        if not self.mode_text:
            return echo(self.mode)
        return f"{echo(self.mode_text)} (taken for {self.mode!r}; map_server refuses it as written)"

    def where(self, key: str) -> str:
        """``YAML:LINE`` of ``key``, or the yaml alone where the key is absent."""
        return f"{self.path}:{self.lines[key]}" if key in self.lines else str(self.path)


def _close_key(key: Any, known: tuple[str, ...] = _KNOWN_KEYS) -> str | None:
    """The map_server key (or other ``known`` name) that ``key``, not one of them, looks like
    a misspelling of (``mdoe``, ``Mode``, ``occupied_tresh``; ``Trinary``), or None. (The
    package's ``did_you_mean``, :mod:`spcopyro.results.semantic_map`, sits in a layer above the
    maps; this reads the same: case-folded, a difflib ratio of at least 0.75.)"""
    close = difflib.get_close_matches(str(key).lower(), known, n=1, cutoff=0.75)
    return close[0] if close else None


def _is_nan(value: Any) -> bool:
    """``nan``, ``-nan``, ``.nan`` (any case) as yaml reads them: a float nan or the text."""
    if isinstance(value, float):
        return math.isnan(value)
    return isinstance(value, str) and value.strip().lstrip("+-").lower() in ("nan", ".nan")


_YAML_CPP_DOUBLE = re.compile(
    r"[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?[ \t\n\r\f\v]*"
)
"""The texts yaml-cpp's ``as<double>()`` reads through C++'s ``>>`` (without skipping leading
blanks, ``std::noskipws``; trailing blanks allowed, ``std::ws``): ``0.05``, ``5e-2``, ``.5``,
``010`` (ten), ``0.05 ``. Not `` 0.05``, ``1_000``, ``0x10`` or ``1:30`` (a number, another number
or sexagesimal to PyYAML's YAML 1.1)."""

_YAML_CPP_SPECIAL = {
    text: value
    for spellings, value in (
        ((".inf", ".Inf", ".INF", "+.inf", "+.Inf", "+.INF"), math.inf),
        (("-.inf", "-.Inf", "-.INF"), -math.inf),
        ((".nan", ".NaN", ".NAN"), math.nan),
    )
    for text in spellings
}
"""The texts yaml-cpp's ``as<double>()`` reads as infinities and nan where ``>>`` fails (exactly
these spellings, no blanks; PyYAML reads the same ones unquoted)."""


def _yaml_cpp_number(text: str | None, value: Any) -> Any:
    """A number key's value as map_server reads it: the scalar's ``text`` (quotes removed; None
    for a list or mapping) through yaml-cpp's ``as<double>()``, which converts it whether or not
    it was quoted (``"0.05"``, ``'.inf'``) -- an int where the text is one -- or the text where
    yaml-cpp reads no number from it (`` 0.05``, ``1_000``: refused by the checks that follow,
    as map_server refuses it). ``value`` (PyYAML's reading) where ``text`` is None."""
    if text is None:
        return value
    if text in _YAML_CPP_SPECIAL:
        return _YAML_CPP_SPECIAL[text]
    if _YAML_CPP_DOUBLE.fullmatch(text) is None:
        return text
    digits = text.rstrip()
    return int(digits) if re.fullmatch(r"[-+]?[0-9]+", digits) else float(digits)


def _number_hint(text: Any) -> str:
    """Why yaml-cpp reads no number from a string value ``text`` that looks like one: blanks
    before it (inside quotes), or YAML 1.1 forms PyYAML reads and yaml-cpp does not."""
    if not isinstance(text, str):
        return ""
    if text != text.lstrip() and _yaml_cpp_number(text.lstrip(), None) != text.lstrip():
        return (f": map_server (yaml-cpp) reads no number with blanks before it; write "
                f"{text.strip()}")  # fmt: skip
    return ""


_YAML_CPP_BOOLS = {
    text: word in ("y", "yes", "true", "on")
    for word in ("y", "yes", "true", "on", "n", "no", "false", "off")
    for text in (word, word.upper(), word.capitalize())
}
"""The texts yaml-cpp's ``as<bool>()`` reads (quoted or not): Nav2's map_io reads ``negate`` as
an int, else as a bool, so ``negate: "true"`` or ``negate: y`` (a string to PyYAML) negate there.
(ROS 1's map_server reads only an int: ``negate: true`` fails there.)"""


_YAML_CPP_INT = re.compile(
    r"[-+]?(?:0[xX](?P<hex>[0-9a-fA-F]+)|0(?P<oct>[0-7]+)|(?P<dec>[1-9][0-9]*|0))\s*"
)
"""The texts yaml-cpp's ``as<int>()`` reads: C++'s ``>>`` of an int with the base its prefix
gives (``0x`` hex, a leading 0 octal), signed, trailing blanks allowed. ``1_000``, ``0b1``,
``1.0`` or ``09`` (ints or floats to PyYAML, or strings) are not ints there."""

_INT32 = (-(2**31), 2**31 - 1)
"""The range of C++'s ``int`` (map_io's ``as<int>()``, ROS 1's ``int negate``): an integer beyond
it does not parse as an int there."""


def _negate(text: str | None, value: Any) -> bool | None:
    """``negate`` as map_server reads it, or None where it does not read (module docstring of
    :mod:`spcopyro.maps.map_server`): ``text`` (the scalar's text, quotes removed; None for a list
    or mapping) as yaml-cpp's int (ROS 1 and Nav2 pass it on as a C++ bool: any nonzero int
    negates), else as yaml-cpp's bool (Nav2 only). ``value`` is PyYAML's reading of it."""
    if text is None or isinstance(value, float):
        return None
    match = _YAML_CPP_INT.fullmatch(text)
    if match is None:
        return _YAML_CPP_BOOLS.get(text)
    digits, base = next(
        (match[g], b) for g, b in (("hex", 16), ("oct", 8), ("dec", 10)) if match[g]
    )
    number = int(digits, base) * (-1 if text.startswith("-") else 1)
    return number != 0 if _INT32[0] <= number <= _INT32[1] else None


def _check_thresholds(doc: dict[str, Any], where: Callable[[str], str], warn: bool = True) -> None:
    """Refuse thresholds that are not numbers, nan (map_server's comparisons with it are all
    false) or swapped (``free_thresh`` above ``occupied_thresh``); warn of one outside [0, 1],
    which map_server reads (``p`` is in [0, 1], so it reads as 0 or 1) but which is most likely
    a percentage or a slip: it makes every pixel, or none, free or occupied (unless not
    ``warn``)."""
    for key in ("occupied_thresh", "free_thresh"):
        value = doc[key]
        if not is_number(value) or math.isnan(value):
            raise MapFormatError(
                f"{where(key)}: key {key!r} must be a number (a probability in [0, 1]), "
                f"got {echo(value)}"
            )
    free, occupied = doc["free_thresh"], doc["occupied_thresh"]
    if free > occupied:  # equal: map_server reads them (module doc)
        raise MapFormatError(
            f"{where('free_thresh')}: key 'free_thresh' ({echo(free)}) must not exceed "
            f"'occupied_thresh' ({echo(occupied)}): swapped?"
        )
    effects = {
        "occupied_thresh": ("every pixel reads occupied", "no pixel reads occupied"),
        "free_thresh": ("no pixel reads free", "every pixel not occupied reads free"),
    }
    for key, (below, above) in effects.items():
        value = doc[key]
        if warn and not 0.0 <= value <= 1.0:
            logger.warning(
                "%s: key %r %s is outside [0, 1], where a pixel's occupancy p lies: %s, as "
                "map_server reads it%s",
                where(key), key, echo(value), below if value < 0 else above,
                f"; a percentage? write {value / 100:g}" if 1 < value <= 100 else "",
            )  # fmt: skip


_SEPARATING_TABS = re.compile(r"(?<=[:,\[\]])[ \t]*\t[ \t]*|[ \t]*\t[ \t]*(?=#|$)", re.MULTILINE)
"""Runs of blanks holding a tab after a key's or a flow list's separator, or before a comment or
a line's end: white space to yaml-cpp, an error to PyYAML (tabs that indent are not YAML)."""


_UNDECODED = {byte: 0xF0000 + byte - 0xDC00 for byte in range(0xDC80, 0xDD00)}
"""surrogateescape's stand-ins (U+DC80..U+DCFF) for bytes that are not UTF-8 -> private-use
code points (U+F0080..U+F00FF), which PyYAML reads (it refuses surrogates)."""
_UNDECODED_BACK = {code: byte for byte, code in _UNDECODED.items()}


class _ShownBytes(logging.Filter):
    """:data:`logger`'s filter: each warning of a map yaml or its image (this module's and
    :mod:`~spcopyro.maps.map_server`'s) with each byte that is not UTF-8 shown as ``\\xe9``, as
    a :class:`MapFormatError` shows it (:func:`~spcopyro._util.messages.shown_bytes` of the
    whole text, as its ``__init__`` does): a misspelt key's warning showed it as its stand-in,
    ``'mod\\U000f00e9'``, a JPEG's name as its surrogate, ``'carte\\udce9.jpg'``."""

    def filter(self, record: logging.LogRecord) -> bool:
        record.msg = shown_bytes(record.getMessage())
        record.args = ()
        return True


logger.addFilter(_ShownBytes())


def _yaml_text(data: bytes) -> str:
    """A map yaml's bytes as text, read as yaml-cpp (map_server) reads them: UTF-16 after its
    byte-order mark (Windows' "Unicode"), else UTF-8 with any byte that is not UTF-8 passed
    through (a latin-1 or Shift-JIS comment, an image name in the file system's own bytes) as a
    :data:`_UNDECODED` stand-in; ``image`` turns them back into its bytes."""
    if data[:2] in (b"\xff\xfe", b"\xfe\xff"):
        return data.decode("utf-16")
    return data.decode("utf-8", "surrogateescape").translate(_UNDECODED)


_TAB_INDENT = re.compile(r"^ *\t[ \t]*[\w.-]+[ \t]*:[^\n]*", re.MULTILINE)
"""A key's line indented by a tab (PyYAML and yaml-cpp refuse it), from its start to its end."""


def _parse_yaml(text: str) -> tuple[Any, Any]:
    """(the root node, the document) of a map yaml; yaml.YAMLError if it does not parse."""
    import yaml

    return yaml.compose(text, Loader=_map_yaml_loader()), yaml.load(text, Loader=_map_yaml_loader())


def read_map_yaml(
    yaml_path: str | os.PathLike, accepts: tuple[str, ...] = _MODES, warn: bool = True
) -> _MapYaml:
    """Parse and validate a map_server yaml; errors name the file, line, key and value; its
    warnings (a misspelt key, a resolution or threshold out of range) are logged unless not
    ``warn`` (a second read of a yaml already loaded, :mod:`~spcopyro.maps.free_space`'s).

    A ``mode`` that is not map_server's but looks like one (``Trinary``, ``SCALE``) gets a
    did-you-mean where the caller ``accepts`` that one; where the caller refuses it anyway, it
    is read as that one (``mode_text`` keeps what was written) so that the caller's refusal
    says why at once, not after a second try."""
    import yaml

    path = Path(yaml_path)
    if not path.is_file():
        raise MapFileNotFoundError(f"{path}: map yaml not found")
    if path.suffix.lower() in (".pgm", ".png", ".bmp", ".jpg", ".jpeg", ".tif", ".tiff"):
        raise MapFormatError(f"{path}: the map's image; give its yaml (the file that names "
                             "this image, its resolution and origin)")  # fmt: skip
    try:
        text = _yaml_text(path.read_bytes())
    except OSError as err:
        raise MapFormatError(f"{path}: cannot read map yaml: {err}") from err
    try:
        root, doc = _parse_yaml(text)
    except yaml.YAMLError as err:
        untabbed = _SEPARATING_TABS.sub(lambda m: m.group().replace("\t", " "), text)
        try:  # PyYAML refuses a tab after "key:", which yaml-cpp (map_server) reads as a space
            root, doc = _parse_yaml(untabbed)
        except yaml.YAMLError:
            if tabbed := _TAB_INDENT.search(untabbed):
                line = untabbed.count("\n", 0, tabbed.start()) + 1
                raise MapFormatError(
                    f"{path}:{line}: a tab indents {echo(tabbed[0].strip())}: YAML indents with "
                    "spaces only, and map_server's yaml-cpp refuses it too ('illegal map value'): "
                    "remove it (a map yaml's keys start their lines)"
                ) from err
            raise MapFormatError(f"{path}: invalid yaml: {err}") from err
    if not isinstance(doc, dict) or not isinstance(root, yaml.MappingNode):
        raise MapFormatError(
            f"{path}: map yaml must be a mapping of keys to values, got {type(doc).__name__}"
        )
    lines: dict[Any, int] = {}
    texts: dict[Any, str] = {}  # each scalar value's text, quotes removed, as yaml-cpp reads it
    items: dict[Any, list[str | None]] = {}  # a list value's items' texts (None: not a scalar)
    for key_node, value_node in root.value:
        if not isinstance(key_node, yaml.ScalarNode):
            raise MapFormatError(
                f"{path}:{key_node.start_mark.line + 1}: map yaml keys must be plain names"
            )
        key = key_node.value
        if key in lines:
            raise MapFormatError(
                f"{path}:{key_node.start_mark.line + 1}: duplicate key {echo(key)} "
                f"(first at line {lines[key]})"
            )
        lines[key] = key_node.start_mark.line + 1
        if isinstance(value_node, yaml.ScalarNode):
            texts[key] = value_node.value
        elif isinstance(value_node, yaml.SequenceNode):
            items[key] = [
                n.value if isinstance(n, yaml.ScalarNode) else None for n in value_node.value
            ]

    def where(key: str) -> str:
        return f"{path}:{lines[key]}" if key in lines else str(path)

    misspelt = {
        key: close
        for key in doc
        if key not in _KNOWN_KEYS and (close := _close_key(key)) is not None
    }
    for key in _REQUIRED_KEYS:
        if key not in doc:
            typo = [f"{where(k)} has {echo(k)}" for k, close in misspelt.items() if close == key]
            hint = f" ({', '.join(typo)}: misspelt?)" if typo else ""
            raise MapFormatError(
                f"{path}: missing required key {key!r}, {_KEY_MEANINGS[key]}{hint}"
            )
    for key, close in misspelt.items() if warn else ():
        logger.warning(
            "%s: unknown key %s ignored, as map_server ignores it: did you mean %r?",
            where(key), echo(key), close,
        )  # fmt: skip

    for key in ("resolution", "occupied_thresh", "free_thresh"):
        doc[key] = _yaml_cpp_number(texts.get(key), doc[key])
    if isinstance(doc["origin"], list) and len(items.get("origin", ())) == len(doc["origin"]):
        doc["origin"] = [
            _yaml_cpp_number(t, v) for t, v in zip(items["origin"], doc["origin"], strict=True)
        ]

    def bad(key: str, expected: str) -> MapFormatError:
        value = doc[key]
        hint = next((h for v in (value if isinstance(value, list) else [value])
                     if (h := _number_hint(v))), "")  # fmt: skip
        return MapFormatError(
            f"{where(key)}: key {key!r} must be {expected}, got {echo(value)}{hint}"
        )

    resolution = doc["resolution"]
    if not is_positive_number(resolution):
        raise bad("resolution", "a positive finite number")
    low, high = PLAUSIBLE_RESOLUTION
    if warn and not low <= resolution <= high:
        logger.warning(
            "%s: key 'resolution' %s: cells of %s m%s (a robot's map is usually 0.05 m a cell): "
            "is it written in %s?",
            where("resolution"), echo(resolution), f"{resolution:g}",
            f", wider than {high:g} m, would hold whole rooms" if resolution > high
            else f", narrower than {low:g} m, make a house a few centimetres across",
            "millimetres or centimetres" if resolution > high else "kilometres",
        )  # fmt: skip

    origin = doc["origin"]
    if (
        not isinstance(origin, list)
        or len(origin) != 3
        or not all(is_finite_number(v) for v in origin)
    ):
        error = bad("origin", "a list of 3 finite numbers [x, y, yaw]")
        if isinstance(origin, list) and len(origin) == 3 and _is_nan(origin[2]):
            error = MapFormatError(
                f"{error}: ROS 1's map_saver writes a yaw of nan for a map published with an "
                "invalid (zero) orientation quaternion, as some mapping packages do; "
                "map_server refuses it too: the map is not rotated, write 0"
            )
        raise error
    if abs(origin[2]) > MAX_YAW_NOISE:
        raise MapFormatError(
            f"{where('origin')}: key 'origin' has yaw {echo(origin[2])}; rotated maps are not "
            "supported (yaw must be 0): rotate the observations' positions by -yaw about the "
            "origin's x, y into the image's axes and write yaw 0 (the fit's maps and masks are "
            "then in those axes)"
        )

    negate = _negate(texts.get("negate"), doc["negate"])
    if negate is None:
        raise bad("negate", "an integer (0: white is free; any other: black is free) or a boolean")
    _check_thresholds(doc, where, warn)

    mode = mode_text = doc.get("mode", "trinary")
    if mode not in _MODES:
        close = _close_key(mode, _MODES)  # map_server compares them case-sensitively
        if close is None or close in accepts:
            error = bad("mode", "one of 'trinary', 'scale', 'raw'")
            raise MapFormatError(f"{error}; did you mean {close!r}?") if close else error
        mode = close  # the caller refuses it as that mode, saying why (shown_mode)

    image = doc["image"]
    if not isinstance(image, str) or not image:
        raise bad("image", "a non-empty file name")
    image_path = Path(image.translate(_UNDECODED_BACK))  # the name's own bytes (_yaml_text)
    if not image_path.is_absolute():
        image_path = path.parent / image_path

    return _MapYaml(
        path=path,
        image=image_path,
        resolution=float(resolution),
        origin=(float(origin[0]), float(origin[1]), 0.0),  # yaw: 0 or noise (MAX_YAW_NOISE)
        negate=bool(negate),
        negate_text=texts["negate"],
        occupied_thresh=float(doc["occupied_thresh"]),
        free_thresh=float(doc["free_thresh"]),
        mode=mode,
        mode_text=str(mode_text) if mode != mode_text else "",
        lines=dict(lines),
    )
