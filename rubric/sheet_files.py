"""A sheet read from its YAML or JSON text, refusing before anything is built what the service could not hold.

Python reads and writes an integer as decimal text only up to MAX_INTEGER_DIGITS digits (its int-string limit): a
longer one fails inside the YAML or JSON parser, and one built from YAML's short forms (hex, octal, binary) fails
later, when the sheet is stored as JSON. YAML 1.1 also reads `1:59:59` as the base-60 integer 7199 (and `1:30.5` as a
float), which nobody writing a sheet means and which reaches any size in few characters: refused too. A refusal names
the field by its dotted path in the sheet (`configs.extension.substeps`) and the rule (SheetTextError).

One reader for every door that takes a sheet as text: the sheet page's import (grader.services.submissions.sheet_form,
which also refuses aliases and deep nesting), `grader submit` (grader.client) and `grader grade`; the API's JSON bodies
pass `whole_number` to the JSON parser (grader.web.bodies).
"""

from __future__ import annotations

import json
from typing import Any

import yaml
from yaml.resolver import Resolver

# Python's default int-string limit (sys.get_int_max_str_digits()): the longest integer json and yaml read or write.
MAX_INTEGER_DIGITS = 4300
_TOO_BIG = 10 ** MAX_INTEGER_DIGITS
# libyaml's C parser where PyYAML was built with it (the pure-Python one took 0.4 s for the largest sheet the sheet
# page's caps admit); the same safe types either way.
_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_RESOLVER = Resolver()
_INT, _FLOAT = "tag:yaml.org,2002:int", "tag:yaml.org,2002:float"
TOO_LONG = f"a whole number may have at most {MAX_INTEGER_DIGITS} digits"
BASE_60 = ("base-60 numbers such as 1:59:59 (YAML 1.1 reads it as 7199) are not accepted: write the number in "
           "decimal, or quote it if it is text")


class SheetTextError(ValueError):
    """The sheet's text cannot be read: `field` is the dotted path in the sheet ("file" for the whole text)."""

    def __init__(self, field: str, rule: str):
        super().__init__(f"{field}: {rule}")
        self.field, self.rule = field, rule


class TooLongInteger:
    """What `whole_number` gives the JSON parser for an integer past MAX_INTEGER_DIGITS digits, so that the one who
    walks the parsed value can name its field."""

    def __init__(self, digits: int):
        self.digits = digits

    @property
    def rule(self) -> str:
        return f"{TOO_LONG}, this one has {self.digits}"


def whole_number(text: str) -> int | TooLongInteger:
    """json.loads(parse_int=...): the integer, or a TooLongInteger where Python could not hold it as text."""
    digits = len(text.lstrip("-"))
    return TooLongInteger(digits) if digits > MAX_INTEGER_DIGITS else int(text)


def _integer_rule(text: str) -> str | None:
    """Why a YAML 1.1 integer scalar cannot be held (as PyYAML's SafeConstructor would build it), or None."""
    value = text.replace("_", "").lstrip("+-")
    if ":" in value:
        return BASE_60
    base, digits = ((2, value[2:]) if value.startswith("0b") else (16, value[2:]) if value.startswith("0x")
                    else (8, value) if value.startswith("0") and value != "0" else (10, value))
    if base == 10 and len(digits) > MAX_INTEGER_DIGITS:
        return f"{TOO_LONG}, this one has {len(digits)}"
    try:
        number = int(digits, base)  # bounded: decimal by the check above, powers of two linear in the text's length
    except ValueError:
        return f"must be a whole number, got {text[:40]!r}"
    return f"{TOO_LONG} once written in decimal" if number >= _TOO_BIG else None


def _scalar_rule(event: yaml.ScalarEvent) -> str | None:
    tag = event.tag
    if tag is None or tag == "!":
        tag = _RESOLVER.resolve(yaml.ScalarNode, event.value, event.implicit)
    if tag == _INT:
        return _integer_rule(event.value)
    if tag == _FLOAT and ":" in event.value:
        return BASE_60
    return None


def yaml_problem(text: str, *, max_depth: int | None = None, aliases: bool = True) -> SheetTextError | None:
    """What in the YAML's events may not be loaded, or None: a number the service cannot hold (always), an alias
    (`aliases=False`: a few aliased lines can stand for gigabytes once stored as JSON), nesting past `max_depth`
    (the loader composes nested nodes recursively). One pass over the parser's events, which builds nothing; each
    refusal names its field's path. Raises yaml.YAMLError for text that is no YAML."""
    # One entry per open mapping or sequence: [its label in its parent, is a mapping, a key comes next, the current
    # key, the current index].
    stack: list[list[Any]] = []

    def here() -> str | None:
        """The label of the node the parser gives next, in the innermost open collection ("?" for a key)."""
        if not stack:
            return None
        top = stack[-1]
        return ("?" if top[2] else top[3]) if top[1] else str(top[4])

    def field(label: str | None) -> str:
        return ".".join([frame[0] for frame in stack[1:]] + ([label] if label is not None else [])) or "file"

    def advance() -> None:
        if stack:
            top = stack[-1]
            if top[1]:
                top[2] = not top[2]
            else:
                top[4] += 1

    for event in yaml.parse(text, Loader=_LOADER):
        if isinstance(event, yaml.AliasEvent):
            if not aliases:
                return SheetTextError(field(here()), "aliases (*name) are not accepted")
            advance()
        elif isinstance(event, yaml.ScalarEvent):
            is_key = bool(stack) and stack[-1][1] and stack[-1][2]
            if (rule := _scalar_rule(event)) is not None:
                return SheetTextError(field(None if is_key else here()), rule + (" (in a key)" if is_key else ""))
            if is_key:
                stack[-1][3] = event.value
            advance()
        elif isinstance(event, yaml.MappingStartEvent | yaml.SequenceStartEvent):
            label = here() or "file"
            if stack and stack[-1][1] and stack[-1][2]:
                stack[-1][3] = "?"  # a collection as a key: the value after it is named "?"
            stack.append([label, isinstance(event, yaml.MappingStartEvent), True, "?", 0])
            if max_depth is not None and len(stack) > max_depth + 1:
                return SheetTextError(field(None), f"nested more than {max_depth} levels deep")
        elif isinstance(event, yaml.MappingEndEvent | yaml.SequenceEndEvent):
            stack.pop()
            advance()
    return None


def load_yaml(text: str, *, max_depth: int | None = None, aliases: bool = True) -> Any:
    """The YAML's data (JSON is YAML too) by PyYAML's safe loader, once `yaml_problem` found nothing; SheetTextError
    otherwise, field "file" for text that is no YAML (or that a safe constructor refuses: `!!int abc`)."""
    try:
        if (problem := yaml_problem(text, max_depth=max_depth, aliases=aliases)) is not None:
            raise problem
        return yaml.load(text, Loader=_LOADER)  # noqa: S506 - a safe loader, and its events were checked above
    except (yaml.YAMLError, RecursionError, ValueError, LookupError, TypeError, AttributeError) as exc:
        if isinstance(exc, SheetTextError):
            raise
        # A safe constructor's own errors on an explicit tag (`!!bool maybe`: KeyError) are no readable YAML either.
        raise SheetTextError("file", f"not readable YAML: {exc}") from None


def too_long_integer(value: Any) -> SheetTextError | None:
    """The first TooLongInteger in JSON data parsed with `whole_number`, named by its path; iterative."""
    stack: list[tuple[Any, tuple[str, ...]]] = [(value, ())]
    while stack:
        item, path = stack.pop()
        if isinstance(item, TooLongInteger):
            return SheetTextError(".".join(path) or "file", item.rule)
        if isinstance(item, dict | list):
            children = item.items() if isinstance(item, dict) else enumerate(item)
            stack.extend((child, (*path, str(key))) for key, child in reversed(list(children)))
    return None


def load_json(text: str) -> Any:
    """The JSON's data; SheetTextError naming the field of an integer Python cannot hold, or "file" for no JSON."""
    try:
        data = json.loads(text, parse_int=whole_number)
    except (ValueError, RecursionError) as exc:
        raise SheetTextError("file", f"not readable JSON: {exc}") from None
    if (problem := too_long_integer(data)) is not None:
        raise problem
    return data
