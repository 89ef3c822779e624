"""What every command's parser shares: the defaults in ``--help``, and the old spellings of
renamed options kept working (docs/commands.md, "Option names").

A renamed option's old spelling is rewritten to the new one before the command's parser reads
the line, with a one-line notice on stderr: the new option keeps its own checks (``required``,
its type, its number of values), the old one is not listed in ``--help``, and scripts written
for the old name still run.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence


class DefaultsFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Add "(default: X)" once: not where the help already names its default, and not for
    options without one (None) or for on/off flags."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        if "default" in text.lower() or any(action.default is x for x in (None, False, argparse.SUPPRESS)):
            return text
        return super()._get_help_string(action)


class CommandParser(argparse.ArgumentParser):
    """A command's parser: its ``--help`` shows the defaults, and it reads the old spellings of
    its renamed options (:func:`renamed`) as the new ones."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        kwargs.setdefault("formatter_class", DefaultsFormatter)
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        #: old spelling -> the new option(s) its values go to, in order
        self.renamed: dict[str, tuple[str, ...]] = {}

    def parse_known_args(self, args: Sequence[str] | None = None, namespace=None):  # type: ignore[override]
        argv = list(sys.argv[1:] if args is None else args)
        return super().parse_known_args(self._new_spellings(argv), namespace)

    def _new_spellings(self, argv: list[str]) -> list[str]:
        if not self.renamed:
            return argv
        out: list[str] = []
        i = 0
        while i < len(argv):
            word = argv[i]
            i += 1
            if word == "--":  # what follows is not options
                return out + argv[i - 1 :]
            old, eq, value = word.partition("=")
            new = self.renamed.get(old)
            if new is None:
                out.append(word)
                continue
            print(notice(self.prog, old, new), file=sys.stderr)
            if len(new) == 1:
                out.append(f"{new[0]}={value}" if eq else new[0])
                continue
            # one old option with a value per new option: --tau UP DOWN -> --tau-up UP --tau-down DOWN
            values = argv[i : i + len(new)]
            i += len(values)
            for name, v in zip(new, values, strict=False):
                out += [name, v]
            if len(values) < len(new):
                out.append(new[len(values)])  # the new option then says a value is missing
        return out


def notice(prog: str, old: str, new: tuple[str, ...]) -> str:
    """The one line an old spelling prints."""
    now = new[0] if len(new) == 1 else " and ".join(new) + ", one value each"
    return f"{prog}: {old} is now {now} (the old name still works, for now)"


def renamed(parser: argparse.ArgumentParser, old: str, *new: str) -> None:
    """Read ``old`` as ``new`` in this parser, with a notice. Several ``new`` options take one
    value each of the old option's values, in order. Only a :class:`CommandParser` reads old
    spellings (``slopelander``'s own); another parser refuses them as unknown options."""
    known = {s for a in parser._actions for s in a.option_strings}
    missing = [n for n in new if n not in known]
    if missing or old in known:
        raise ValueError(f"renamed({old!r} -> {new!r}): the parser has {sorted(known)}")
    if isinstance(parser, CommandParser):
        parser.renamed[old] = tuple(new)
