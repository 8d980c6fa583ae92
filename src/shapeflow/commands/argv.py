"""The operations' command-line grammar: a parser that tells usage errors in the user's terms, and
options objects from what it parsed.

``shapeflow COMMAND ...`` and the OPERATION of ``shapeflow batch`` are the same words, so both parse
them with these parsers: :class:`CommandParser` (a usage error is one line on stderr, exit 2) and
:class:`RaisingParser` (a usage error is a :class:`~shapeflow.errors.ParameterError`).  Each
operation's sub-parser names its options class (``set_defaults(options=FlowOptions)``);
:func:`options_from` builds it from the parsed values.
"""

from __future__ import annotations

import argparse
import contextvars
import dataclasses
import difflib
import re
import sys

from ..errors import ParameterError

__all__ = ["CommandParser", "RaisingParser", "options_from"]

_NUM = r"(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?|inf|infinity|nan"
#: numbers written as option values, negative ones included (-5, -1e3, -.5, -inf, -90,10): values, not options
_NUMBER = re.compile(rf"^-({_NUM})(,\s*[-+]?({_NUM}))*$", re.IGNORECASE)
#: the parser that parses now (the subcommand's once it has begun): errors are told in its name
_ACTIVE: contextvars.ContextVar = contextvars.ContextVar("shapeflow_cli_parser", default=None)


class CommandParser(argparse.ArgumentParser):
    """The command line's parser: every usage error is one line in the user's terms with a hint,
    ``shapeflow enhance: error: unrecognized argument --strenght; did you mean --strength? (see
    'shapeflow enhance --help')``, never a usage dump; misspelt commands, options and choices get a
    "did you mean" (difflib); negative numbers such as ``-1e3`` and ``-inf`` are values."""

    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        self._negative_number_matcher = _NUMBER
        self._words: list[str] = []

    def parse_known_args(self, args=None, namespace=None):
        self._words = list(sys.argv[1:] if args is None else args)
        _ACTIVE.set(self)
        return super().parse_known_args(args, namespace)

    def error(self, message):
        parser = self.teller(message)
        print(f"{parser.prog}: error: {parser.explain(message)} (see '{parser.prog} --help')", file=sys.stderr)
        sys.exit(2)

    def teller(self, message: str) -> CommandParser:
        """The parser whose terms tell the error: the top level reports a subcommand's stray words
        ("unrecognized arguments"), which the subcommand tells unless they came before it."""
        active = _ACTIVE.get()
        if message.startswith("unrecognized arguments") and isinstance(active, CommandParser) \
                and active is not self and self._unknown_option() is None:
            return active
        return self

    # -- the message ---------------------------------------------------------------------------

    def explain(self, message: str) -> str:
        """argparse's ``message`` in one line of the user's terms."""
        unknown = self._unknown_option()
        if unknown is not None and not message.startswith("argument COMMAND"):
            return unknown
        m = re.match(r"argument (\S+): invalid choice: '(.*)' \(choose from (.*)\)$", message)
        if m:
            name, value = m.group(1), m.group(2)
            choices = re.findall(r"'([^']*)'", m.group(3)) or [c.strip() for c in m.group(3).split(",")]
            if name == "COMMAND":
                return f"unknown command {value!r}{_did_you_mean(value, choices)}"
            return f"{_long(name)} must be one of {', '.join(choices)}, got {value!r}{_did_you_mean(value, choices)}"
        m = re.match(r"argument (\S+): invalid (float|int) value: '(.*)'$", message)
        if m:
            kind = "a number" if m.group(2) == "float" else "an integer"
            return f"{_long(m.group(1))} must be {kind}, got {m.group(3)!r}"
        m = re.match(r"argument (\S+): expected one argument$", message)
        if m:
            return f"{_long(m.group(1))} needs a value"
        m = re.match(r"the following arguments are required: (.*)$", message)
        if m:
            names = [_long(n) for n in m.group(1).split(", ")]
            return f"missing {', '.join(names)} (required)"
        m = re.match(r"unrecognized arguments: (.*)$", message)
        if m:
            return f"unexpected argument(s) {m.group(1)}"
        return message[0].lower() + message[1:] if message else "bad usage"

    def _unknown_option(self) -> str | None:
        """The first word that looks like an option of this parser and is none, with a suggestion."""
        known = sorted(self._option_string_actions)
        for word in self._words:
            if word == "--":
                return None
            if self._subcommand_word(word):
                return None     # the rest is the subcommand's
            if not word.startswith("-") or word == "-" or _NUMBER.match(word):
                continue
            name = word.split("=", 1)[0]
            if name in known or (name.startswith("--") and len([k for k in known if k.startswith(name)]) == 1):
                continue
            if not name.startswith("--") and len(name) > 2 and name[:2] in known:
                continue        # -n3: a short option with its value attached
            return f"unrecognized argument {name}{_did_you_mean(name, [k for k in known if k.startswith('--')])}"
        return None

    def _subcommand_word(self, word: str) -> bool:
        return any(isinstance(a, argparse._SubParsersAction) and word in a.choices for a in self._actions)


def _long(names: str) -> str:
    """'--strength/-s' -> '--strength'."""
    parts = names.split("/")
    return next((p for p in parts if p.startswith("--")), parts[0])


def _did_you_mean(word: str, choices) -> str:
    close = difflib.get_close_matches(word, list(choices), n=1, cutoff=0.6)
    return f"; did you mean {close[0]}?" if close else ""


class RaisingParser(CommandParser):
    """An argument parser whose errors raise :class:`ParameterError` instead of exiting (the batch
    runner checks each step of an operation with it)."""

    def error(self, message):
        parser = self.teller(message)
        raise ParameterError(f"{parser.prog}: {parser.explain(message)}")


def options_from(args: argparse.Namespace):
    """The options object of a parsed operation: the class its sub-parser named, built from the
    parsed values of its fields (which check themselves)."""
    cls = args.options
    return cls(**{f.name: getattr(args, f.name) for f in dataclasses.fields(cls)
                  if f.init and hasattr(args, f.name)})
