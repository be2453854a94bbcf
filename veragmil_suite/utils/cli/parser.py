"""The parser every console program builds (one spelling convention, old spellings hidden), and robosuite's and
robomimic's own scripts' parsers adopted into it.
"""

from __future__ import annotations

import argparse
import ast
import contextlib
import copy
import inspect
import sys
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import TYPE_CHECKING, Any, NoReturn

from veragmil_suite.utils.cli.kinds import Choice, Kind, ListOf, image_side
from veragmil_suite.utils.numbers import first_repeated
from veragmil_suite.utils.whole_files import same_file

if TYPE_CHECKING:
    import types


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Descriptions as written, defaults shown (where there is one), an option's old spellings left out."""

    def _get_help_string(self, action: argparse.Action) -> str:
        help = action.help or ""
        default = action.default
        switch = isinstance(action, (argparse._StoreTrueAction, argparse._StoreFalseAction))
        if "default" in help or switch or default is None or default is argparse.SUPPRESS or default == []:
            return help
        shown = " ".join(map(str, default)) if isinstance(default, (list, tuple)) else str(default)
        shown = shown.replace("%", "%%")
        return f"{help} (default: {shown})".strip()

    def _format_action_invocation(self, action: argparse.Action) -> str:
        hidden = getattr(action, "aliases", ())
        if hidden:
            action = copy.copy(action)
            action.option_strings = [s for s in action.option_strings if s not in hidden]
        return super()._format_action_invocation(action)


class Flatten(argparse.Action):
    """Stores the items of a ListOf option's values as one list; an item given twice is refused (each list names a
    set: foods, cameras, demos, seeds, algorithms; twice would do the same work twice, or fail on it part-way)."""

    def __call__(self, parser, namespace, values, option_string=None):
        items = [item for value in values for item in value]
        twice = first_repeated(items)
        if twice is not None:
            parser.error(f"argument {option_string or self.metavar or self.dest}: {twice} given twice")
        setattr(namespace, self.dest, items)


class _HeightWidth(argparse.Action):
    """An old ``--size H [W]`` option: sets camera_height and camera_width (W defaults to H)."""

    def __call__(self, parser, namespace, values, option_string=None):
        if len(values) > 2:
            parser.error(f"argument {option_string}: takes HEIGHT [WIDTH], got {len(values)} values")
        namespace.camera_height, namespace.camera_width = (list(values) * 2)[:2]


def add_image_size(parser: Parser, height: int, width: int, old: Iterable[str] = ()) -> None:
    """--camera-height and --camera-width (robomimic's names), in pixels; ``old`` spellings of a combined
    ``H [W]`` option stay accepted, hidden."""
    parser.add_argument("--camera-height", type=image_side, default=height, metavar="PX", help="image height, pixels")
    parser.add_argument("--camera-width", type=image_side, default=width, metavar="PX", help="image width, pixels")
    if old:
        parser.add_argument(*old, type=image_side, nargs="+", action=_HeightWidth, dest=argparse.SUPPRESS,
                            default=argparse.SUPPRESS, help=argparse.SUPPRESS)  # fmt: skip


def option_strings(parser: argparse.ArgumentParser) -> set[str]:
    return {s for action in parser._actions for s in action.option_strings}


def respell(parser: argparse.ArgumentParser, argv: list[str]) -> list[str]:
    """``argv`` with each long option spelled as ``parser`` knows it: --n-rollouts as --n_rollouts where the parser
    has the latter, and the reverse (up to a bare ``--``, after which nothing is an option)."""
    known = option_strings(parser)
    out = []
    for i, token in enumerate(argv):
        if token == "--":
            return out + list(argv[i:])
        if token.startswith("--") and len(token) > 2:
            name, eq, value = token.partition("=")
            if name not in known:
                for other in ("--" + name[2:].replace("_", "-"), "--" + name[2:].replace("-", "_")):
                    if other in known:
                        token = other + eq + value
                        break
        out.append(token)
    return out


def adopt(parser: argparse.ArgumentParser, prog: str) -> Parser:
    """An upstream script's parser (robomimic's) as one of ours: named ``prog``, each long option shown with dashes
    (--n-rollouts) and its own spelling (--n_rollouts) kept as a hidden alias, our help and spelling rule. Its
    abbreviations stay allowed, as upstream allows them."""
    parser.__class__ = Parser
    parser.prog = prog
    parser.formatter_class = HelpFormatter
    for action in parser._actions:
        dashed = [s[:2] + s[2:].replace("_", "-") if s.startswith("--") else s for s in action.option_strings]
        aliases = tuple(s for s in action.option_strings if s not in dashed)
        for name in dashed:
            parser._option_string_actions[name] = action
        action.option_strings = list(dict.fromkeys([*dashed, *aliases]))
        action.aliases = aliases
    return parser


class Parser(argparse.ArgumentParser):
    """
    The argparse parser of every console program: no abbreviated options (an abbreviation that is unique today is
    ambiguous after the next option), either spelling of an option (dashes or underscores), old spellings accepted
    but hidden (``aliases=``), a ListOf option stored as one flat list, and a refusal in one line.
    """

    def __init__(self, prog: str, description: str | None = None, **kwargs):
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(prog=prog, description=description, allow_abbrev=False, **kwargs)

    def error(self, message: str) -> NoReturn:
        """A refused command line as one line and exit 2: argparse's usage block above it is what --help is for."""
        self.exit(2, f"{self.prog}: error: {message}\n")

    def add_argument(self, *names: str, aliases: Iterable[str] = (), **kwargs: Any) -> argparse.Action:
        aliases = tuple(aliases)
        kind = kwargs.get("type")
        if (
            isinstance(kind.item if isinstance(kind, ListOf) else kind, Choice)
            and kwargs.get("help") != argparse.SUPPRESS
        ):
            kwargs["help"] = f"{kwargs.get('help') or ''} (%(type)s)".strip()  # the names, listed when --help prints
        if isinstance(kind, ListOf) and kwargs.get("action") in (None, "store"):
            kwargs.setdefault("nargs", "+")
            kwargs["action"] = Flatten
        action = super().add_argument(*names, *aliases, **kwargs)
        action.aliases = aliases
        return action

    def add_input(self, dest: str, option: str, kind: Kind, many: bool = False, help: str | None = None) -> None:
        """An input given as a positional argument or as ``option`` (robomimic's --dataset), either way into
        ``dest``: one of the two is required, and not both."""
        metavar = dest.upper()
        self.add_argument(f"{dest}", nargs="*" if many else "?", type=kind, metavar=metavar, help=help)
        self.add_argument(
            option, dest=f"{dest}_option", nargs="+" if many else None, type=kind, metavar=metavar,
            help=f"the same as {metavar}",
        )  # fmt: skip
        self._inputs = [*getattr(self, "_inputs", []), (dest, option, many)]

    def parse_known_args(
        self, args: Sequence[str] | None = None, namespace: argparse.Namespace | None = None
    ) -> tuple[argparse.Namespace, list[str]]:
        args = sys.argv[1:] if args is None else list(args)
        namespace, extras = super().parse_known_args(respell(self, args), namespace)
        for dest, option, many in getattr(self, "_inputs", []):
            given, flagged = getattr(namespace, dest, None), getattr(namespace, f"{dest}_option", None)
            if given and flagged:
                self.error(f"give {dest.upper()} or {option}, not both")
            paths = (given or flagged) if many else []
            twice = first_repeated(paths or [], same_file)
            if twice is not None:
                self.error(f"{dest.upper()} {twice} is given twice")
            if not given and not flagged:
                self.error(f"give {dest.upper()}{' (one or more)' if many else ''} or {option}")
            setattr(namespace, dest, given or flagged)
            delattr(namespace, f"{dest}_option")
        return namespace, extras


def main_block(module: types.ModuleType) -> object:
    """The compiled body of a script's ``if __name__ == "__main__":`` block (its argparse and its call)."""
    path = inspect.getsourcefile(module)
    with open(path) as f:
        tree = ast.parse(f.read(), filename=path)
    for node in tree.body:
        test = node.test if isinstance(node, ast.If) else None
        if (
            isinstance(test, ast.Compare)
            and isinstance(test.left, ast.Name)
            and test.left.id == "__name__"
            and isinstance(test.comparators[0], ast.Constant)
            and test.comparators[0].value == "__main__"
        ):
            return compile(ast.Module(body=node.body, type_ignores=[]), path, "exec")
    raise RuntimeError(f"{path} has no __main__ block to run")


class _Captured(Exception):
    def __init__(self, parser: argparse.ArgumentParser):
        self.parser = parser


@contextlib.contextmanager
def parse_args_answering(answer: Callable[[argparse.ArgumentParser], argparse.Namespace]) -> Iterator[None]:
    """Within: every ArgumentParser.parse_args returns ``answer(parser)`` (the script's own parser is built as
    robomimic wrote it, and what it parses is decided here)."""
    original = argparse.ArgumentParser.parse_args
    argparse.ArgumentParser.parse_args = lambda self, *args, **kwargs: answer(self)
    try:
        yield
    finally:
        argparse.ArgumentParser.parse_args = original


def _raise_captured(parser: argparse.ArgumentParser) -> argparse.Namespace:
    raise _Captured(parser)


def script_parser(module: types.ModuleType) -> argparse.ArgumentParser:
    """The parser a script's ``if __name__ == "__main__":`` block builds (robosuite's and robomimic's scripts build
    theirs there), taken at its parse_args: nothing after that runs."""
    try:
        with parse_args_answering(_raise_captured):
            exec(main_block(module), dict(module.__dict__))
    except _Captured as captured:
        return captured.parser
    raise RuntimeError(f"{module.__name__}'s __main__ block parsed no arguments")
