"""The operations' command-line grammar: a parser that tells usage errors in the user's terms, and
options objects from what it parsed.

``shapeflow COMMAND ...`` and the OPERATION of ``shapeflow batch`` are the same words, so both parse
them with these parsers: :class:`CommandParser` (a usage error is one line on stderr, exit 2) and
:class:`RaisingParser` (a usage error is a :class:`~shapeflow.errors.ParameterError`).  Each
operation's sub-parser names its options class (``set_defaults(options=FlowOptions)``);
:func:`options_from` builds it from the parsed values.

An option's value is the word after it when that word is one of its values, even a word that starts
with '-' (``--front -z``, as ``--front=-z``); an option whose value may be left out
(:class:`OptionalValue`: ``--feature-lines [DEG|marked]``) takes the next word only if it is one of
its values, so ``render part.ply --feature-lines out.png`` draws 30° lines into out.png.
"""

from __future__ import annotations

import argparse
import contextvars
import dataclasses
import difflib
import re
import sys

from ..errors import ParameterError

__all__ = ["CommandParser", "RaisingParser", "OptionalValue", "options_from"]

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

    def __init__(self, *args, intermixed: bool = False, **kw):
        super().__init__(*args, **kw)
        self._negative_number_matcher = _NUMBER
        self._words: list[str] = []
        #: positionals may come before and after options (``render a.ply --edges b.ply out.png``)
        self.intermixed = intermixed
        self._mixing = False

    def parse_known_args(self, args=None, namespace=None):
        if self._mixing:            # the passes of parse_known_intermixed_args
            return super().parse_known_args(args, namespace)
        self._words = self._with_values(list(sys.argv[1:] if args is None else args))
        _ACTIVE.set(self)
        if not self.intermixed:
            return super().parse_known_args(self._words, namespace)
        self._mixing = True
        try:
            return super().parse_known_intermixed_args(self._words, namespace)
        finally:
            self._mixing = False

    def _with_values(self, words: list[str]) -> list[str]:
        """``words`` with each option's value joined to it (``--front -z`` -> ``--front=-z``) where the
        value is one of the option's (argparse reads a word that starts with '-' as an option), and
        with an :class:`OptionalValue` given its ``const`` (``--feature-lines=30``) where the next word
        is none of its values (argparse would take any word)."""
        out: list[str] = []
        i = 0
        while i < len(words):
            word = words[i]
            if word == "--" or self._subcommand_word(word):
                return out + words[i:]
            action = self._option_action(word)
            test = _value_test(action) if action is not None else None
            if test is not None:
                if i + 1 < len(words) and (test(words[i + 1]) or self._bad_choice(action, words[i + 1])):
                    out.append(f"{word}={words[i + 1]}")
                    i += 2
                    continue
                if isinstance(action, OptionalValue):
                    word = f"{word}={action.const}"
            out.append(word)
            i += 1
        return out

    def _bad_choice(self, action: argparse.Action, word: str) -> bool:
        """A word after an option of choices that starts with '-' and is no option here (``--front -w``):
        its value, told as none of the choices."""
        return (action.choices is not None and not isinstance(action, OptionalValue) and word.startswith("-")
                and len(word) > 1 and self._option_action(word.split("=", 1)[0]) is None)

    def _option_action(self, word: str) -> argparse.Action | None:
        """The action of ``word`` when it is one of this parser's options written without a value
        (``--front``, or a unique abbreviation such as ``--fro``)."""
        if not word.startswith("-") or "=" in word:
            return None
        actions = self._option_string_actions
        if word in actions:
            return actions[word]
        if word.startswith("--") and self.allow_abbrev:
            found = {actions[k] for k in actions if k.startswith(word)}
            if len(found) == 1:
                return found.pop()
        return None

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


class OptionalValue(argparse.Action):
    """An option whose value may be left out (its ``const`` then): the word after it is its value only
    if ``accepts(word)``, otherwise the option stands alone and the word is left to the rest of the
    command line (a path, another option)."""

    def __init__(self, option_strings, dest, accepts, **kw):
        super().__init__(option_strings, dest, nargs="?", **kw)
        self.accepts = accepts

    def __call__(self, parser, namespace, values, option_string=None):
        setattr(namespace, self.dest, values)


def _value_test(action: argparse.Action):
    """Whether a word is a value of ``action``: its ``accepts``, or one of its choices; None for an
    option without either (or one that takes no value, or several)."""
    if isinstance(action, OptionalValue):
        return action.accepts
    if action.choices is not None and action.nargs is None and not isinstance(action, argparse._SubParsersAction):
        return lambda word: word in action.choices
    return None


def _long(names: str) -> str:
    """'--strength/-s' -> '--strength'."""
    parts = names.split("/")
    return next((p for p in parts if p.startswith("--")), parts[0])


def _did_you_mean(word: str, choices) -> str:
    same = [c for c in choices if c.lower() in (word.lower(), f"+{word.lower()}")]   # -Z, z: too short for difflib
    close = same or difflib.get_close_matches(word, list(choices), n=1, cutoff=0.6)
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
