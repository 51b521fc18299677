"""The words of the synthetic speaker: per-category lexicons, sentence templates, filler words.

Utterances of a synthetic house (:func:`spcopyro.synthetic.make_house`) name the place or one of
its objects (:data:`CATEGORY_LEXICON`; some words, such as "table" and "room", belong to several
categories), as a single word or inside a sentence with filler words (:data:`FILLER_WORDS`).
"""

from __future__ import annotations

from dataclasses import dataclass

from spcopyro.data.text import fold_word, tokenize

__all__ = [
    "CATEGORY_LEXICON",
    "DEFAULT_CATEGORY_NAMES",
    "FILLER_WORDS",
    "OPEN_PLAN_CATEGORIES",
    "CategoryLexicon",
    "lexicon_for",
]


@dataclass(frozen=True)
class CategoryLexicon:
    """The words a speaker uses for one place category.

    ``name_word`` is the single word naming the place (as in the public dataset: "living"),
    ``place_phrase`` the tokens naming it inside a sentence (("living", "room")), and
    ``object_words`` things found there. Words may be shared between categories.
    """

    name_word: str
    place_phrase: tuple[str, ...]
    object_words: tuple[str, ...]

    @property
    def words(self) -> tuple[str, ...]:
        """All distinct words of the category, in order name, phrase, objects."""
        return tuple(dict.fromkeys((self.name_word, *self.place_phrase, *self.object_words)))


def _lex(name: str, phrase: str, objects: str) -> CategoryLexicon:
    return CategoryLexicon(name, tuple(phrase.split()), tuple(objects.split()))


CATEGORY_LEXICON: dict[str, CategoryLexicon] = {
    "kitchen": _lex("kitchen", "kitchen", "refrigerator sink stove table"),
    "living": _lex("living", "living room", "sofa tv table room"),
    "bedroom": _lex("bedroom", "bedroom", "bed closet room"),
    "bathroom": _lex("bathroom", "bathroom", "shower bathtub"),
    "toilet": _lex("toilet", "toilet", "restroom paper"),
    "entrance": _lex("entrance", "entrance", "door shoes"),
    "dining": _lex("dining", "dining room", "table chair room"),
    "study": _lex("study", "study", "desk bookshelf computer room"),
    "washroom": _lex("washroom", "washroom", "washbasin mirror towel"),
    "corridor": _lex("corridor", "corridor", "hallway hall"),
    "closet": _lex("closet", "closet", "clothes hanger"),
    "garage": _lex("garage", "garage", "car bicycle"),
}
"""Words per category name. Shared on purpose: table (kitchen, living, dining), room (living,
bedroom, dining, study), closet (bedroom, closet)."""

DEFAULT_CATEGORY_NAMES: tuple[str, ...] = tuple(CATEGORY_LEXICON)
"""Category names in the order they are used: a house with R regions uses the first R."""

# Sentence templates; "{}" is the place phrase or an object word.
_PLACE_TEMPLATES: tuple[str, ...] = (
    "here is the {}",
    "this is the {}",
    "we are in the {}",
    "this place is the {}",
)
_OBJECT_TEMPLATES: tuple[str, ...] = (
    "there is a {} here",
    "this is the {}",
    "the {} is here",
)
FILLER_WORDS: frozenset[str] = frozenset(
    token
    for template in _PLACE_TEMPLATES + _OBJECT_TEMPLATES
    for token in template.split()
    if token != "{}"
)
"""Tokens of the sentence templates that name no place ("here", "is", "the", ...)."""

OPEN_PLAN_CATEGORIES: tuple[str, ...] = ("living", "kitchen", "dining", "entrance", "corridor")
"""Categories that open-plan rooms prefer, best first (an LDK: living + kitchen + dining)."""


def is_category_token(name: object) -> bool:
    """Whether ``name`` can be a category's word: one token as :func:`spcopyro.data.tokenize`
    reads it (lower case, no space, no punctuation at its ends), in NFKC form as ``where`` reads
    words, and without a comma (St.csv's separator). ``kitchen``, ``living-room`` and ``台所``
    are; ``Kitchen`` and ``two words`` are not."""
    if not isinstance(name, str) or "," in name:
        return False
    return tokenize(name) == (name,) and fold_word(name) == name


def lexicon_for(name: str) -> CategoryLexicon:
    """The lexicon of a category name; a name outside :data:`CATEGORY_LEXICON` is its own word."""
    return CATEGORY_LEXICON.get(name, CategoryLexicon(name, (name,), ()))
