r"""From an instruction to the places it names, and from a place word to a goal cell.

**Instruction** (:func:`parse_instruction`). The instruction is split into lower-case words
(letters of any script with their marks, digits, ``_``, ``'`` and ``-``; NFC-composed), each
read as ``spcopyro where`` reads a word (:func:`~spcopyro.results.semantic_map.word_key`:
``"台所"``, ``"CAFÉ"`` and a decomposed ``"café"`` find the fit's ``台所`` and ``café``).
Connecting and filler words (:data:`STOP_WORDS`: "go", "to", "the", "via", "then", ...) are
skipped even when the fit's vocabulary holds them (a fit on sentences does). Every other word
of the vocabulary names a place. A word outside it with a close known word
(:func:`~spcopyro.results.semantic_map.close_words`, as ``spcopyro where`` suggests: "kitchn",
"livingroom"; not "bathroom" for "bedroom") is an error that names them (a typo must not send
the robot elsewhere); one with no close word is ignored and reported, unless it names a stop (right
after a connecting word and an article, "via the hall", with no known place in its phrase),
which is an error: the robot would skip that stop. An instruction with a word of
:data:`NEGATION_WORDS` ("not the kitchen", "avoid the kitchen") or of :data:`LEAVE_WORDS`
("leave the kitchen", "stay away from the kitchen", "get out of the kitchen") is refused: the
robot only visits places, so it would have driven to the one it was told to keep away from.
A "no" between two words with only spaces around it, after a known place word, is the particle
of a romanised Japanese instruction ("daidokoro no mae"), skipped (``_particles``); one with a
known place word after it too ("kitchen no bedroom", "shinshitsu no oshiire") is refused: as
English it keeps the robot out of the second place, as the particle it leads there. Places
keep the instruction's spelling for what is shown (:attr:`Instruction.said`: "TV", the fit's
"tv").

The places are visited in the order the instruction gives them, except that a place after
"via", "through" or "past" is visited *before* the destination said just before it: "go to the
bedroom via the corridor" visits the corridor, then the bedroom; "via the corridor to the
bedroom" the same; "to the kitchen via the hall, then the bedroom" the hall, the kitchen, the
bedroom. "then", "to", "and then" end a "via" phrase, and one after them leads to the next
destination: "the kitchen, then via the hall to the bedroom" visits the kitchen, the hall, the
bedroom. A place after "after" or "first" is
visited before the destination said before it too, but is a stop, not a waypoint ("go to the
toilet after the kitchen", "go to the toilet, but first the kitchen"); "after that" and a
"first" right after a place ("the kitchen first, then ...") read as "then". "X before Y" visits X,
then Y; a "before" with no place before it, or "before that", is refused (the order is not
clear from the words).

**Goal** (:func:`choose_goal`). p = p(cell in the place of the word)
(:func:`spcopyro.results.uncertainty.where_probability`: the fit's marginals, or its point estimate)
over the cells the robot fits on (:mod:`spcopyro.robot.navigation.graph`).

1. Candidate regions: the 8-connected components of the allowed cells with
   p >= :data:`AMBIGUITY_RATIO` x max p, each at least :data:`MIN_CANDIDATE_AREA` (the largest
   is kept if none is, with a note: the place is small or uncertain). Two or more candidates
   are separate regions of near-equal probability: the word is **ambiguous**.
2. A candidate the robot cannot reach from where it is (another component of the planning graph)
   is reported and never returned. If none is reachable, :class:`UnreachableGoalError`.
3. Of the reachable candidates, the nearer by path length is taken (``strict``:
   :class:`AmbiguousGoalError` listing them instead).
4. In the chosen region the goal is the cell of largest p, within :data:`P_TOLERANCE` of it the
   cell deepest inside the region (largest distance to the region's edge, so a region of equal
   p -- a point estimate -- gets its middle, not its doorway), then the nearest.
"""

from __future__ import annotations

import unicodedata
from dataclasses import dataclass, field

import numpy as np

from spcopyro._util.messages import area_text, listed
from spcopyro.data.text import hidden_characters_note, hidden_match
from spcopyro.results.semantic_map import did_you_mean, word_key
from spcopyro.results.where import close_to_guess
from spcopyro.robot.navigation.graph import PlanningGrid

__all__ = [
    "AMBIGUITY_RATIO",
    "MIN_CANDIDATE_AREA",
    "LEAVE_WORDS",
    "NEGATION_WORDS",
    "P_TOLERANCE",
    "STOP_WORDS",
    "AmbiguousGoalError",
    "Candidate",
    "GoalChoice",
    "Instruction",
    "NavigationError",
    "UnreachableGoalError",
    "choose_goal",
    "instruction_words",
    "parse_instruction",
]

VIA_WORDS = frozenset({"via", "through", "past", "thru"})
RESET_WORDS = frozenset({"then", "to", "towards", "toward", "into", "finally", "afterwards"})
EARLIER_WORDS = frozenset({"after", "first"})
"""A place said after one of these is visited before the destination said before it ("go to the
toilet after the kitchen", "go to the toilet, but first the kitchen"); "after that" is "then",
and so is "first" right after a place ("the kitchen first, then the bedroom")."""
THAT_WORDS = frozenset({"that", "this", "it", "which", "wards"})
STOP_WORDS = frozenset(
    {"go", "goto", "move", "drive", "walk", "head", "come", "take", "bring", "me", "us", "please",
     "the", "a", "an", "my", "our", "your", "this", "that", "and", "of", "in", "at", "on",
     "by", "way", "room", "area", "place", "here", "there", "is", "it", "robot", "now", "first",
     "next", "after", "before", "back", "along", "from", "then", "to", "towards", "toward",
     "into", "finally", "via", "through", "past", "thru", "out", "over", "up", "down", "just",
     "but", "afterwards"}
)  # fmt: skip
"""Words of an instruction that name no place (module docstring)."""
NEGATION_WORDS = frozenset(
    {"not", "don't", "dont", "never", "avoid", "avoiding", "without", "except", "excluding",
     "no", "nor", "skip", "skipping", "instead", "rather", "unless", "or", "either"}
)  # fmt: skip
"""Words (and any ending in "n't") that would keep the robot away from a place, or leave one
out ("the kitchen or the bedroom", "the kitchen instead of the bedroom"): navigate visits every
place an instruction names, so an instruction holding one is refused ("go to the bathroom, not
the kitchen" drove to both)."""
LEAVE_WORDS = frozenset(
    {"away", "leave", "leaves", "leaving", "exit", "exiting", "bypass", "bypassing",
     "circumvent", "circumventing", "anywhere", "everywhere", "elsewhere", "outside"}
)  # fmt: skip
"""Words that send the robot out of, around or away from the place they name ("leave the
kitchen", "stay away from the kitchen", "anywhere but the kitchen"): refused as
:data:`NEGATION_WORDS` are, unless the fit knows the word (a house whose exit is a place);
so are "out of" and "clear of" ("get out of the kitchen", "steer clear of the kitchen"). Each
was ignored as a word the fit does not know, and the robot drove into the kitchen."""
_LEAVE_PAIRS = frozenset({("out", "of"), ("clear", "of")})
AMBIGUITY_RATIO = 0.8
"""A region whose best p is at least this share of the map's best p is a candidate: with two or
more, the word is ambiguous (near-equal: odds below 1.25)."""
MIN_CANDIDATE_AREA = 0.5
"""Square metres: smaller high-probability patches are not candidate places."""
P_TOLERANCE = 0.02
"""Cells within this of a region's best p count as equally good; the deepest one is the goal."""


class NavigationError(ValueError):
    """An instruction the robot cannot carry out (its message says why)."""


class UnreachableGoalError(NavigationError):
    """No candidate place of a word is reachable from where the robot is."""


class AmbiguousGoalError(NavigationError):
    """``strict`` and a word with two or more candidate places."""


@dataclass(frozen=True)
class Instruction:
    """The places an instruction names, in the order they are visited."""

    text: str
    places: tuple[str, ...]
    """Place words, visiting order (the last is the destination)."""
    via: tuple[bool, ...]
    """Per place: said after "via" (a waypoint)."""
    ignored: tuple[str, ...] = ()
    """Words neither known nor close to a known word (as the instruction spells them)."""
    said: tuple[str, ...] = ()
    """Per place: the word as the instruction spells it ("TV" for the fit's "tv"); empty:
    :attr:`places` (an Instruction built by hand)."""

    def spelling(self, index: int) -> str:
        """Place ``index`` as the instruction spells it."""
        return self.said[index] if len(self.said) == len(self.places) else self.places[index]


_APOSTROPHES = str.maketrans({"\u2019": "'", "\u2018": "'", "\u02bc": "'", "\uff07": "'"})


def _words(text: str) -> list[tuple[str, str]]:
    """The words of ``text`` as typed (NFC-composed), each with the text between it and the
    word before it: runs of letters, marks and digits of any script, ``_``, ``'`` and ``-`` (a
    non-ASCII letter split ``café`` into ``caf``, and ``台所`` vanished), with the invisible
    format characters (Unicode Cf) inside them, as the data's tokens keep them (a zero-width
    space split ``kit\u200bchen`` into ``kit`` and ``chen``, a Persian word at its zero-width
    non-joiner)."""
    words, word, gap = [], [], []
    text = text.translate(_APOSTROPHES)  # "don’t", as phones and word processors type it
    for char in unicodedata.normalize("NFC", text) + " ":
        category = unicodedata.category(char)
        if char in "_'-" or category[0] in "LMN" or (word and category == "Cf"):
            word.append(char)  # a format character inside a word stays, as tokenize keeps it
        elif word:
            ends = len(word)  # a word's trailing format characters go to the gap after it
            while unicodedata.category(word[ends - 1]) == "Cf":
                ends -= 1
            words.append(("".join(word[:ends]), "".join(gap)))
            word, gap = [], [*word[ends:], char]
        else:
            gap.append(char)
    return words


def instruction_words(text: str) -> list[str]:
    """The words of ``text`` as typed (:func:`_words`; ``"-kitchen"`` in "go to the -kitchen"):
    the spellings a stop is shown with (:attr:`Instruction.said`)."""
    return [word for word, _ in _words(text)]


def _tokens(text: str) -> list[str]:
    """The words of ``text`` (:func:`_words`), lower-cased."""
    return [word.lower() for word, _ in _words(text)]


def _particles(tokens: list[str], gaps: list[str], places: list[bool]) -> set[int]:
    """The positions of "no" as the Japanese particle of a romanised instruction ("daidokoro no
    mae", in front of the kitchen), not a negation: it stands between two words with only
    spaces around it, after a place word the fit knows (``places``) or after the word a
    particle led to ("rouka no saki no daidokoro"). "the kitchen, no, the bedroom", "no
    kitchen" and "with no kitchen" are negations."""
    found: set[int] = set()
    for k in range(1, len(tokens) - 1):
        if (tokens[k] == "no" and (places[k - 1] or k - 2 in found)
                and gaps[k].isspace() and gaps[k + 1].isspace()):  # fmt: skip
            found.add(k)
    return found


def parse_instruction(text: str, vocabulary: tuple[str, ...]) -> Instruction:
    """The places of ``text`` (module docstring). ValueError naming the close known words for a
    misspelt word, or when no place word is left; :class:`NavigationError` for a word of
    :data:`NEGATION_WORDS`."""
    known = {word.lower() for word in vocabulary}
    candidates = sorted(known - STOP_WORDS)
    places: list[str] = []
    via: list[bool] = []
    ignored: list[str] = []
    mode, destination = "to", None  # destination: index of the last destination in places
    words = _words(text)
    tokens = [word.lower() for word, _ in words]
    gaps = [gap for _, gap in words]
    keys = [word_key(vocabulary, token).lower() for token in tokens]
    is_place = [key in known and token not in STOP_WORDS | NEGATION_WORDS | LEAVE_WORDS
                for token, key in zip(tokens, keys, strict=True)]  # fmt: skip
    particles = _particles(tokens, gaps, is_place)
    both = next((k for k in sorted(particles) if is_place[k - 1] and is_place[k + 1]), None)
    if both is not None:  # "kitchen no bedroom": "not the bedroom", or "the kitchen's bedroom"?
        before, after = words[both - 1][0], words[both + 1][0]
        raise NavigationError(
            f"the instruction {text!r} says 'no' between two places, {before!r} and {after!r}: "
            f"as English ('{before}, no {after}') it keeps the robot out of {after!r}, as the "
            f"particle of a romanised Japanese instruction ('{before} no {after}', the {after} "
            f"of the {before}) it leads on to {after!r}; navigate cannot tell which, and visits "
            f"every place an instruction names: name only the places to visit, in order ('{before} "
            f"{after}', or '{before}' alone)"
        )
    negation = next((token for k, token in enumerate(tokens)
                     if (token in NEGATION_WORDS and k not in particles) or token.endswith("n't")
                     or (token in LEAVE_WORDS and token not in known)), None)  # fmt: skip
    negation = negation or next((f"{a} {b}" for a, b in zip(tokens, tokens[1:], strict=False)
                                 if (a, b) in _LEAVE_PAIRS), None)  # fmt: skip
    if negation is not None:
        raise NavigationError(
            f"the instruction {text!r} says {negation!r}: navigate visits every place an "
            "instruction names, in order, and cannot keep the robot away from one or choose "
            "between them; name only the places to visit (to keep it out of a place: spcopyro "
            "export --nav2 DIR --word WORD --mode keepout)"
        )
    last_place = -2  # the token index of the last place word
    spelled: list[str] = []  # the instruction's spelling of each place ("TV", not "tv")
    for k, token in enumerate(tokens):
        key = keys[k]
        token = key if key in known else token
        following = tokens[k + 1] if k + 1 < len(tokens) else ""
        if k in particles:  # "daidokoro no mae": the place's particle, neither place nor "no"
            continue
        if token in VIA_WORDS:
            mode = "via"
            continue
        if token in RESET_WORDS or (token == "after" and following in THAT_WORDS):
            mode = "to"  # a later "via" leads to the next destination, not back before the
            destination = None  # last ("the kitchen, then via the hall to the bedroom")
            continue
        if token in EARLIER_WORDS:  # but "the kitchen first, then ...": the kitchen is first
            mode = "to" if token == "first" and last_place == k - 1 else "earlier"
            continue
        if token == "before":  # "X before Y": then; "before Y, X" and "before that": refused
            if not places or following in THAT_WORDS:
                raise NavigationError(
                    f"the instruction {text!r} says 'before' where navigate cannot tell the "
                    "order of the places from it; say them in the order to visit them (go to "
                    "the bathroom, then the kitchen)"
                )
            mode = "to"
            continue
        if token in STOP_WORDS:
            continue
        if token not in known:
            if hidden_match(token, vocabulary):  # 'kit\u200bchen' prints as 'kitchen'
                raise ValueError(
                    f"word {words[k][0]!r} of the instruction is not in the fit's vocabulary "
                    f"of {len(vocabulary)} words: {hidden_characters_note(words[k][0], vocabulary)}"
                )
            hint = did_you_mean(token, candidates)
            if hint:
                raise ValueError(
                    f"word {token!r} of the instruction is not in the fit's vocabulary of "
                    f"{len(vocabulary)} words{hint}"
                )
            ignored.append(words[k][0])
            continue
        last_place = k
        if mode in ("via", "earlier") and destination is not None:
            places.insert(destination, token)
            via.insert(destination, mode == "via")
            spelled.insert(destination, words[k][0])
            destination += 1
        else:
            places.append(token)
            via.append(mode == "via")
            spelled.append(words[k][0])
            if mode == "to":
                destination = len(places) - 1
    skipped = _unknown_stop(tokens, known, vocabulary) if places else None
    if skipped is not None:  # "via the corridor": the robot drove past no corridor
        raise ValueError(
            f"word {skipped[1]!r} of the instruction names a stop ({skipped[0]!r}) that is not "
            f"in the fit's vocabulary: navigate would skip it and drive to "
            f"{', '.join(places)} only; name the places the fit knows (its words: "
            f"{listed(candidates)})"
        )
    if not places:
        if not words:  # '' or ' ?! ': it said "the instruction '' names no place the fit knows"
            shown = listed(candidates) if candidates else "none"  # not "known words: " alone
            example = candidates[0] if candidates else "kitchen"
            opening = (f"{'is empty' if not text.strip() else 'has no words'}: name the places "
                       f"to visit, in order, e.g. 'go to the {example}'")  # fmt: skip
        else:
            shown = listed(candidates) if candidates else (
                "none: the fit has no word that can name a place (fitted without words, or only "
                "connecting words such as 'the' heard)")  # fmt: skip
            extra = f" (ignored: {', '.join(ignored)})" if ignored else ""
            opening = f"names no place the fit knows{extra}"
        raise ValueError(f"the instruction {text!r} {opening}; known words: {shown}")
    stops: list[tuple[str, bool, str]] = []  # "kitchen kitchen" made two identical stops
    for place, waypoint, said in zip(places, via, spelled, strict=True):
        if stops and stops[-1][0] == place:  # the same place again: one stop, a destination
            stops[-1] = (place, stops[-1][1] and waypoint, stops[-1][2])  # if either names it
        else:  # one; said as it was said first
            stops.append((place, waypoint, said))
    return Instruction(text, tuple(p for p, _, _ in stops), tuple(v for _, v, _ in stops),
                       tuple(ignored), tuple(s for _, _, s in stops))  # fmt: skip


_PLACE_ARTICLES = frozenset({"the", "a", "an", "my", "our", "your"})
_PHRASE_ENDS = VIA_WORDS | RESET_WORDS | EARLIER_WORDS | {"before", "and"}


def _unknown_stop(
    tokens: list[str], known: set[str], vocabulary: tuple[str, ...]
) -> tuple[str, str] | None:
    """(the words, the unknown word) of the first stop named by a word the fit does not know:
    one right after a connecting word and an article ("via the corridor", "then to the
    start", "to the parlor and ...") whose phrase, up to the next connecting word, holds no
    known place ("to the big kitchen" does); None when every stop is known."""

    def is_known(token: str) -> bool:
        return word_key(vocabulary, token).lower() in known and token not in STOP_WORDS

    for k in range(2, len(tokens)):
        connector, article, word = tokens[k - 2], tokens[k - 1], tokens[k]
        if connector not in _PHRASE_ENDS or article not in _PLACE_ARTICLES:
            continue
        if word in STOP_WORDS or is_known(word):
            continue
        rest = tokens[k + 1 :]
        end = next((i for i, t in enumerate(rest) if t in _PHRASE_ENDS), len(rest))
        if not any(is_known(t) for t in rest[:end]):
            return f"{connector} {article} {word}", word
    return None


@dataclass(frozen=True)
class Candidate:
    """One separate region of high probability for a word."""

    node: int
    """Its best cell (allowed index; the goal if chosen)."""
    xy: tuple[float, float]
    probability: float
    """p at its best cell."""
    area: float
    """Square metres of its allowed cells (those with the robot's clearance): less than the
    place's whole area that ``where`` reports, by the band along its walls."""
    distance: float
    """Path length from where the robot is, metres (inf: unreachable)."""

    @property
    def reachable(self) -> bool:
        return bool(np.isfinite(self.distance))


@dataclass(frozen=True)
class GoalChoice:
    """The goal of one place word."""

    word: str
    node: int
    candidate: Candidate
    candidates: tuple[Candidate, ...]
    """Every candidate region, best p first."""
    notes: tuple[str, ...] = field(default_factory=tuple)
    where_odds: float = float("inf")
    """``where``'s posterior odds of the word's concept over the runner-up (inf: none); below
    :data:`~spcopyro.results.where.ODDS_WARNING` ``where`` warns that its answer is not clearly
    more probable than the runner-up."""
    concept: int = -1
    """``where``'s concept for the word (-1: not asked)."""
    shared_with: tuple[tuple[str, float], ...] = ()
    """The other words ``where`` answers with the same concept (:attr:`WhereAnswer.shared_with
    <spcopyro.results.where.WhereAnswer.shared_with>`): 'toilet' sent to a concept that
    'living' names too may be a goal in the living room."""

    @property
    def ambiguous(self) -> bool:
        return sum(c.reachable for c in self.candidates) > 1

    @property
    def close_to_guess(self) -> bool:
        """``where`` warns that the word's answer is not clearly more probable than the
        runner-up (:attr:`where_odds` below :data:`~spcopyro.results.where.ODDS_WARNING`)."""
        return close_to_guess(self.where_odds)


def _components(mask: np.ndarray) -> tuple[np.ndarray, int]:
    from scipy.ndimage import label

    return label(mask, structure=np.ones((3, 3), dtype=bool))


def _depth(mask: np.ndarray) -> np.ndarray:
    from scipy.ndimage import distance_transform_edt

    return distance_transform_edt(np.pad(mask, 1, constant_values=False))[1:-1, 1:-1]


def choose_goal(
    planning: PlanningGrid,
    word: str,
    probability: np.ndarray,
    distance: np.ndarray,
    *,
    strict: bool = False,
) -> GoalChoice:
    """The goal of ``word`` (module docstring).

    Args:
        planning: the cells the robot fits on.
        word: the place word (for messages).
        probability: ``[N]`` p(cell in the word's place) over the fit's free cells.
        distance: ``[M]`` path length in metres from where the robot is to every allowed cell
            (:func:`~spcopyro.robot.navigation.graph.shortest_paths`).
        strict: an ambiguous word is an error instead of the nearer candidate.
    """
    grid = planning.grid
    if planning.num_allowed == 0:
        raise UnreachableGoalError(
            f"no free cell has {planning.radius:g} m of clearance: the robot fits nowhere"
        )
    nodes = np.arange(planning.num_allowed)
    p_node = np.asarray(probability, dtype=np.float64)[planning.free_index_of(nodes)]  # [M]
    p_image = np.full(grid.shape, -np.inf)  # [H, W]
    cells = planning.cells(nodes)  # [M, 2]
    p_image[cells[:, 0], cells[:, 1]] = p_node
    best = float(p_node.max())
    strong = p_image >= AMBIGUITY_RATIO * best  # [H, W]
    labels, count = _components(strong)
    sizes = np.bincount(labels.ravel(), minlength=count + 1)[1:]  # [count]
    cell_area = grid.resolution**2
    keep = [k + 1 for k in range(count) if sizes[k] * cell_area >= MIN_CANDIDATE_AREA]
    small = not keep  # no patch is a place's size: the largest is the goal, with a warning
    if small:
        keep = [int(np.argmax(sizes)) + 1]
    candidates = []
    for k in keep:
        region = labels == k  # [H, W]
        rows, cols = np.nonzero(region)
        region_nodes = planning.allowed.free_index[rows, cols]  # [n]
        p = p_node[region_nodes]
        top = p >= p.max() - P_TOLERANCE
        depth = _depth(region)[rows, cols]  # [n] cells
        d = distance[region_nodes]
        order = np.lexsort((region_nodes, d, -depth, ~top))  # top, deepest, nearest, index
        node = int(region_nodes[order[0]])
        xy = grid.cell_to_world(planning.cells(np.array([node]))[0])
        candidates.append(Candidate(node, (float(xy[0]), float(xy[1])), float(p_node[node]),
                                    float(region.sum() * cell_area),
                                    float(distance[node])))  # fmt: skip
    candidates.sort(key=lambda c: (-c.probability, -c.area, c.node))
    reachable = [c for c in candidates if c.reachable]
    notes = []
    for c in candidates:
        if not c.reachable:
            notes.append(
                f"{word!r}: the region at x={c.xy[0]:.2f} y={c.xy[1]:.2f} "
                f"(p(cell is the place) = {c.probability:.3f}, {area_text(c.area)} m^2) cannot be "
                f"reached from here with {planning.radius:g} m of clearance; not a goal"
            )
    if not reachable:
        raise UnreachableGoalError(
            f"no place of {word!r} is reachable: " + "; ".join(n.split(": ", 1)[1] for n in notes)
        )
    if len(reachable) > 1 and strict:
        regions = "; ".join(
            f"x={c.xy[0]:.2f} y={c.xy[1]:.2f} (p(cell is the place) = {c.probability:.3f}, "
            f"{c.distance:.1f} m away)"
            for c in reachable
        )
        raise AmbiguousGoalError(
            f"{word!r} is ambiguous: {len(reachable)} separate regions of near-equal probability "
            f"({regions}); --strict takes none of them (leave it out to take the nearer)"
        )
    chosen = min(reachable, key=lambda c: (c.distance, -c.probability, c.node))
    if small:  # a speck at a room's edge was driven to without a word
        notes.append(
            f"{word!r}: no patch of cells the robot fits on with p(cell is the place) >= "
            f"{AMBIGUITY_RATIO:g} x the best ({best:.3f}) covers {MIN_CANDIDATE_AREA:g} m^2; "
            f"the goal is in the largest, {area_text(chosen.area)} m^2: the place is small, or "
            "uncertain on this fit "
            "(`spcopyro where` shows its probability; a longer fit sharpens it)"
        )
    return GoalChoice(word, chosen.node, chosen, tuple(candidates), tuple(notes))
