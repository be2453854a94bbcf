"""
Every console program's command line, walked from setup.py (and the benchmark scripts, run as python
benchmarks/NAME.py): each option takes a kind of value
(veragmil_suite.utils.cli), and this table GENERATES its cases from the parsers themselves: every option of every
console program is fed values of the wrong type, out of range, and paths that are missing, a directory, read-only
or too long, and each must be refused in one line naming the option, exit 2. A program or an option added tomorrow
is covered the day it is added (a program without cli.command, or an option without a kind, fails here).

The convention is walked the same way: option names (lowercase words and dashes; either spelling accepted), one
kind per name across programs, lists taking spaces and commas alike, old spellings hidden but accepted, and the
commands committed in results/*/RUN.md still parsing.
"""

import argparse
import ast
import functools
import os
import re
import shlex
import subprocess
from pathlib import Path

import pytest
from helpers.forked_programs import ProgramServer
from helpers.programs import BENCHMARKS, BIN, ENTRY_POINTS, MODULE_PROGRAMS, PROGRAMS, ROOT, command_of, main_of

from veragmil_suite.utils import cli

# programs that run robomimic's own scripts: robomimic's option names, shown with dashes, its underscores accepted
ROBOMIMIC_PROGRAMS = {p for p, target in ENTRY_POINTS.items() if target.startswith("veragmil_suite.scripts.robomimic")}
# python -m MODULE: the module's name, as the shell splits the command, names its program
MODULE_TOKENS = {program.split()[-1]: program for program in MODULE_PROGRAMS}
# one name, two upstream meanings: robosuite's and robomimic's tools both use these words, for different things
UPSTREAM_HOMONYMS = {
    "--config": "veragmil-collect: robosuite's env configuration; veragmil-train: robomimic's config file",
    "--agent": "veragmil-evaluate: any agent SPEC; veragmil-run-agent: robomimic's checkpoint",
}
# old spellings, each accepted (hidden) where its new name is; a new option may not take an old name
OLD_SPELLINGS = {
    "--robot": "--robots",
    "--workers": "--processes",
    "--cameras": "--camera-names",
    "--video-camera": "--camera",
    "--ratio": "--valid-ratio",
    "--skip": "--video-skip",
}


@functools.cache
def parser_of(program: str) -> argparse.ArgumentParser:
    return main_of(program).build_parser()


def value_actions(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    """The options and positionals that take a value (not flags, not --help), hidden ones included."""
    return [a for a in parser._actions if a.nargs != 0]


def name_of(action: argparse.Action) -> str:
    return action.option_strings[0] if action.option_strings else (action.metavar or action.dest)


def argv_for(action: argparse.Action, value: str) -> list[str]:
    return [action.option_strings[0], value] if action.option_strings else [value]


# ---------------------------------------------------------------------------------------------------------------- #
# Bad values, by kind                                                                                              #
# ---------------------------------------------------------------------------------------------------------------- #


@pytest.fixture(scope="module")
def paths(tmp_path_factory) -> dict[str, str]:
    """Paths for the path kinds' bad values: missing, a directory, read-only, too long, a file of the wrong content."""
    root = tmp_path_factory.mktemp("cli")
    (root / "folder").mkdir()
    (root / "notes.txt").write_text("{not JSON, HDF5 or a checkpoint")
    read_only = root / "read_only"
    read_only.mkdir()
    read_only.chmod(0o555)
    if os.access(read_only, os.W_OK):  # root writes anywhere: take a folder the kernel keeps read-only
        read_only = next((Path(p) for p in ("/proc/sys", "/sys/fs") if not os.access(p, os.W_OK)), None)
    return {
        "missing": str(root / "missing" / "file.hdf5"),
        "missing_file": str(root / "missing.hdf5"),
        "folder": str(root / "folder"),
        "text": str(root / "notes.txt"),
        "read_only": str(read_only / "new.hdf5") if read_only else "",
        "too_long": str(root / ("n" * 250 + ".hdf5")),
        "far_too_long": str(root / ("n" * 300)),
    }


def bad_values(kind: cli.Kind, paths: dict[str, str]) -> list[tuple[str, str]]:
    """(what is wrong, the text) for every way a value of ``kind`` can be wrong; a kind not known here fails."""
    if isinstance(kind, cli.ListOf):
        return [("empty item", "a,,b"), *[(f"item {label}", text) for label, text in bad_values(kind.item, paths)]]
    if isinstance(kind, cli.KeyValue):
        return [("no =", "novalue"), *[(f"key {label}", f"{text}=1") for label, text in bad_values(kind.key, paths)]]
    if isinstance(kind, cli.ControlFreq):
        return [("wrong type", "fast"), ("not finite", "nan"), ("hangs robosuite", "1e-9"), ("not a divisor", "7")]
    if isinstance(kind, cli.Integer):
        cases = [("wrong type", "many"), ("a fraction", "1.5")]
        if kind.low is not None:
            cases.append(("below range", str(kind.low - 1)))
        if kind.high is not None:
            cases.append(("above range", str(kind.high + 1)))
        return cases
    if isinstance(kind, cli.Real):
        cases = [("wrong type", "some"), ("not a number", "nan"), ("infinite", "inf")]
        if kind.low is not None:
            cases.append(("below range", repr(kind.low if kind.open_low else kind.low - 1)))
        if kind.high is not None:
            cases.append(("above range", repr(kind.high if kind.open_high else kind.high + 1)))
        return cases
    if isinstance(kind, cli.Choice):
        return [("unknown name", "no-such-" + kind.what.replace(" ", "-"))]
    if isinstance(kind, (cli.Text,)):
        return [("empty", ""), ("two lines", "a\nb")]
    if isinstance(kind, cli.RayAddress):
        return [("a space", "head 6379"), ("two lines", "a\nb")]
    if isinstance(kind, cli.Boolean):
        return [("not a truth value", "maybe")]
    if isinstance(kind, cli.Robot):
        return [("unknown robot", "Nonexistent"), ("two arms", "Baxter")]
    if isinstance(kind, cli.Controller):
        return [("unknown", "BOGUS"), ("not OSC", "IK_POSE"), ("missing file", paths["missing_file"][:-5] + ".json")]
    if isinstance(kind, cli.PhysicsTimestep):
        return [("wrong type", "short"), ("a zero fraction", "1/0"), ("negative", "-1/240"), ("not a divisor", "1/250")]
    if isinstance(kind, cli.SolverOption):
        return [("no =", "iterations"), ("unknown key", "bogus=3"), ("not positive", "iterations=0")] + [
            ("unknown word", "solver=Fast")
        ]
    if isinstance(kind, cli.Url):
        return [
            ("no scheme", "localhost:8765"),
            ("another scheme", "ftp://localhost/"),
            ("bad port", "http://h:99999/"),
        ]
    if isinstance(kind, cli.Port):
        return [("wrong type", "http"), ("below range", "-1"), ("above range", "65536")]
    if isinstance(kind, cli.Host):
        return [("not an address", "999.1.1.1"), ("not this machine", "192.0.2.1")]
    if isinstance(kind, cli.InputFile):
        cases = [("missing", paths["missing_file"]), ("a directory", paths["folder"])]
        cases += [("name too long", paths["far_too_long"])]
        return cases + ([("wrong content", paths["text"])] if kind.check is not None else [])
    if isinstance(kind, cli.InputFolder):
        cases = [("missing", paths["missing_file"]), ("a file", paths["text"])]
        cases += [("name too long", paths["far_too_long"])]
        return cases + ([("without what it holds", paths["folder"])] if kind.holds else [])
    if isinstance(kind, cli.OutputFile):
        cases = [("a directory", paths["folder"]), ("missing folder", paths["missing"])]
        cases += [("name too long", paths["too_long"])]
        if kind.suffixes:
            cases.append(("not a video name", paths["text"]))
        return cases + ([("read-only folder", paths["read_only"])] if paths["read_only"] else [])
    if isinstance(kind, cli.OutputFolder):
        cases = [("a file", paths["text"]), ("under a file", paths["text"] + "/sub")]
        cases += [("name too long", paths["too_long"])]
        return cases + ([("read-only folder", paths["read_only"])] if paths["read_only"] else [])
    if isinstance(kind, cli.FileName):
        return [("a path", "a/b.hdf5"), ("empty", ""), ("name too long", "n" * 300)]
    if isinstance(kind, cli.EnvKwargs):
        return [
            ("not JSON", "{"),
            ("not an object", "[1]"),
            ("unknown argument", '{"bogus": 1}'),
            ("negative grains", '{"n_grains": -1}'),
            ("too many grains", '{"n_grains": 100000, "pile_variants": 1}'),
            ("unknown camera", '{"camera_names": "nocam"}'),
            ("rate that hangs robosuite", '{"control_freq": 1e-9}'),
            ("wrong type", '{"use_camera_obs": "yes"}'),
            ("negative horizon", '{"horizon": -5}'),
            ("unknown food", '{"food": "sushi"}'),
            ("unknown robot", '{"robots": "Nonexistent"}'),
        ]
    if isinstance(kind, cli.Agent):
        return [
            ("unknown form", "robot.pkl"),
            ("unknown profile", "X=expert:sloppy"),
            ("missing dataset", "dataset:" + paths["missing_file"]),
            ("missing checkpoint", paths["missing_file"][:-5] + ".pth"),
        ]
    raise AssertionError(f"no bad values known for {type(kind).__name__}: add them to bad_values")


def refusal(parser: argparse.ArgumentParser, argv: list[str], capsys) -> tuple[object, list[str], str]:
    """(exit code, the program's error lines, all of stderr) of parsing ``argv``."""
    capsys.readouterr()
    try:
        parser.parse_args(argv)
        code = 0
    except SystemExit as stop:
        code = stop.code
    err = capsys.readouterr().err
    return code, [line for line in err.splitlines() if line.startswith(f"{parser.prog}: ")], err


@pytest.mark.parametrize("program", PROGRAMS)
def test_every_option_refuses_every_kind_of_bad_value_in_one_line(program, paths, capsys):
    parser = parser_of(program)
    cases = [(a, label, text) for a in value_actions(parser) for label, text in bad_values(a.type, paths)]
    assert cases, f"{program}: no options walked"
    failures = []
    for action, label, text in cases:
        code, lines, err = refusal(parser, argv_for(action, text), capsys)
        name = name_of(action)
        if code != 2 or len(lines) != 1 or f"argument {name}" not in lines[0] or "Traceback" in err:
            failures.append(f"{name} {label} ({text[:40]!r}): exit {code}, said {lines or err[-300:]}")
    assert not failures, f"{program}: {len(failures)} of {len(cases)} bad values not refused in one line:\n" + (
        "\n".join(failures)
    )


def test_the_table_covers_every_option_of_every_program(paths):
    """Each console program is walked, and the table holds hundreds of cases (a few per option)."""
    total = 0
    for program in PROGRAMS:
        actions = value_actions(parser_of(program))
        total += sum(len(bad_values(a.type, paths)) for a in actions)
    assert total > 300, total


@pytest.mark.parametrize("program", PROGRAMS)
def test_every_program_is_built_by_cli_and_every_value_has_a_kind(program):
    main = main_of(program)
    assert hasattr(main, "build_parser"), f"{program}: its main is not made by cli.command"
    parser = parser_of(program)
    assert isinstance(parser, cli.Parser), f"{program}: parser is not cli.Parser (spellings, lists, no abbreviations)"
    untyped = [name_of(a) for a in parser._actions if a.nargs != 0 and not isinstance(a.type, cli.Kind)]
    assert not untyped, f"{program}: options without a kind of value (veragmil_suite.utils.cli): {untyped}"


# modules with a __main__ block that are not programs a user gives options to: processes the package starts itself
# with arguments of its own making, and a setup step that takes none
NOT_USER_PROGRAMS = {
    "veragmil_suite.devices.vr.render": "the VR server's renderer process (its config from the server)",
    "veragmil_suite.study.logged_run": "a study piece's process (its call from the study)",
    "veragmil_suite.private_macros": "writes robosuite's and robomimic's private macros; no options",
}


def _runnable_modules() -> set[str]:
    """The package's modules that python -m runs: those with a module-level __main__ block, and each package with a
    __main__.py."""
    found = set()
    for path in sorted((ROOT / "veragmil_suite").rglob("*.py")):
        module = ".".join(path.relative_to(ROOT).with_suffix("").parts)
        if path.name == "__main__.py":
            found.add(module.rsplit(".", 1)[0])
            continue
        for node in ast.parse(path.read_text()).body:
            test = node.test if isinstance(node, ast.If) else None
            if isinstance(test, ast.Compare) and isinstance(test.left, ast.Name) and test.left.id == "__name__":
                found.add(module)
    return found


def test_every_module_run_as_a_program_is_walked_here():
    """A program added tomorrow as python -m MODULE is walked by the tests above the day it is added."""
    entry_modules = {target.split(":")[0] for target in ENTRY_POINTS.values()}
    walked = entry_modules | set(MODULE_TOKENS) | set(NOT_USER_PROGRAMS)
    assert "veragmil_suite.calibration" in _runnable_modules()
    assert _runnable_modules() <= walked, f"not walked: {sorted(_runnable_modules() - walked)} (add to MODULE_PROGRAMS)"


def test_a_sample_of_each_program_refuses_as_a_real_process(paths):
    """A generated case of one program per module, in a process of its own: exit 2, one line, no traceback
    (robosuite's and robomimic's import warnings aside). The first console program runs as the console script a
    user starts; the others are forked from an interpreter that imported the package once (helpers.forked_programs:
    1.3 s of CPU each otherwise). The programs of a module share their entry point's code, which the in-process
    table above runs for each."""
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    sample = {ENTRY_POINTS[p].split(":")[0]: p for p in sorted(ENTRY_POINTS, reverse=True)}
    sample.update({program: program for program in [*BENCHMARKS, *MODULE_PROGRAMS]})
    cases = []
    for program in sorted(sample.values()):
        action = next(a for a in value_actions(parser_of(program)) if a.option_strings)
        label, text = bad_values(action.type, paths)[0]
        cases.append((program, action, [*command_of(program), *argv_for(action, text)]))
    real = next(case for case in cases if case[0] in ENTRY_POINTS)
    program, action, argv = real
    _check_process(program, action, subprocess.run(argv, env=env, capture_output=True, text=True, timeout=300))
    with ProgramServer(env) as server:
        for program, action, argv in (case for case in cases if case is not real):
            _check_process(program, action, server.run(*_launcher(program), argv[len(command_of(program)) - 1 :]))


def _launcher(program: str) -> tuple[str, str]:
    """How the program's command starts it: (kind, target) for ProgramServer.run."""
    if program in BENCHMARKS:
        return "script", str(BENCHMARKS[program])
    if program in MODULE_PROGRAMS:
        return "module", program.split()[-1]
    return "entry", ENTRY_POINTS[program]


def _check_process(program, action, finished):
    out, err = finished.stdout, finished.stderr
    lines = [line for line in err.splitlines() if line.startswith(f"{parser_of(program).prog}: ")]
    assert finished.returncode == 2, (program, err[-2000:])
    assert len(lines) == 1 and f"argument {name_of(action)}" in lines[0], (program, err[-2000:])
    assert "Traceback" not in err + out


# ---------------------------------------------------------------------------------------------------------------- #
# The convention                                                                                                   #
# ---------------------------------------------------------------------------------------------------------------- #


def _visible_names(parser: argparse.ArgumentParser) -> list[tuple[str, argparse.Action]]:
    return [(a.option_strings[0], a) for a in parser._actions if a.option_strings and a.help != argparse.SUPPRESS]


@pytest.mark.parametrize("program", PROGRAMS)
def test_option_names_follow_the_convention(program, capsys):
    parser = parser_of(program)
    # an abbreviation unique today is ambiguous after the next option (robomimic's own scripts allow them)
    assert parser.allow_abbrev is (program in ROBOMIMIC_PROGRAMS)
    capsys.readouterr()
    parser.print_help()
    help_text = capsys.readouterr().out
    for name, action in _visible_names(parser):
        if name.startswith("--"):
            assert re.fullmatch(r"--[a-z0-9]+(-[a-z0-9]+)*", name), f"{program} {name}: lowercase words and dashes"
        assert name not in OLD_SPELLINGS, f"{program} {name}: an old spelling; the option is {OLD_SPELLINGS[name]}"
        for alias in getattr(action, "aliases", ()):
            assert not re.search(rf"{re.escape(alias)}\b", help_text), f"{program}: old spelling {alias} shown"
            assert OLD_SPELLINGS.get(alias, name) == name or alias == "--video-path", (program, alias, name)
    for old, new in OLD_SPELLINGS.items():
        known = cli.option_strings(parser)
        assert old not in known or new in known, f"{program}: {old} accepted but its new name {new} is missing"


def test_an_option_name_means_one_kind_of_value_in_every_program():
    kinds: dict[str, dict[str, str]] = {}
    for program in PROGRAMS:
        for action in value_actions(parser_of(program)):
            for name in action.option_strings:
                if not name.startswith("--"):
                    continue
                kind = action.type.item if isinstance(action.type, cli.ListOf) else action.type
                kinds.setdefault(name.replace("_", "-"), {})[program] = type(kind).__name__
    mixed = {n: k for n, k in kinds.items() if len(set(k.values())) > 1 and n not in UPSTREAM_HOMONYMS}
    assert not mixed, f"one option name, several kinds of value: {mixed}"


def _good_values(kind: cli.Kind) -> list[str]:
    candidates = [*(kind.values[:3] if isinstance(kind, cli.Choice) else []), "1", "2", "0.5", "XArm7", "Panda"]
    good = []
    for text in candidates:
        try:
            kind(text)
        except argparse.ArgumentTypeError:
            continue
        good.append(text)
    return good[:2]


@pytest.mark.parametrize("program", PROGRAMS)
def test_lists_take_spaces_and_commas_alike(program):
    """A list option (not paths, which may hold commas; not a hidden old spelling) takes space- or comma-separated
    values, the same list either way."""
    parser = parser_of(program)
    for action in value_actions(parser):
        if action.nargs not in ("+", "*") or action.help == argparse.SUPPRESS:
            continue
        if isinstance(action.type, cli.InputFile):
            continue
        assert isinstance(action.type, cli.ListOf), f"{program} {name_of(action)}: a list option without cli.ListOf"
        a, b = _good_values(action.type.item)
        spaced, commas = argparse.Namespace(), argparse.Namespace()
        action(parser, spaced, [action.type(a), action.type(b)])
        action(parser, commas, [action.type(f"{a},{b}")])
        assert getattr(spaced, action.dest) == getattr(commas, action.dest) == [action.type.item(v) for v in (a, b)]


@pytest.mark.parametrize("program", PROGRAMS)
def test_either_spelling_of_an_option_is_accepted(program):
    parser = parser_of(program)
    for name in cli.option_strings(parser):
        if not name.startswith("--") or not re.search(r"[a-z0-9][-_][a-z0-9]", name):
            continue
        action = parser._option_string_actions[name]
        for other in ("--" + name[2:].replace("_", "-"), "--" + name[2:].replace("-", "_")):
            spelled, value = cli.respell(parser, [other, "x"])
            assert parser._option_string_actions.get(spelled) is action and value == "x", (program, other)
            spelled, _, value = cli.respell(parser, [f"{other}=x"])[0].partition("=")
            assert parser._option_string_actions.get(spelled) is action and value == "x", (program, other)


def test_upstream_spellings_reach_the_same_options():
    run_agent = parser_of("veragmil-run-agent")
    checkpoint = next((ROOT / "models" / "checkpoints").glob("*.pth"))
    assert run_agent.parse_args(["--agent", str(checkpoint), "--n-rollouts", "3"]).n_rollouts == 3  # --n_rollouts
    collect = parser_of("veragmil-collect")
    parsed = collect.parse_args(["--max_fr", "20", "--robot", "Panda", "--cameras", "agentview", "--output", "x.h5"])
    assert (parsed.max_fr, parsed.robots, parsed.camera_names) == (20.0, "Panda", ["agentview"])
    replay = parser_of("veragmil-replay")
    parsed = replay.parse_args(["--dataset", str(ROOT / "demos" / "scoop.hdf5"), "--size", "48", "--skip", "2"])
    assert (parsed.camera_height, parsed.camera_width, parsed.video_skip) == (48, 48, 2)


def _shell_blocks(text: str) -> list[str]:
    """The fenced blocks of a markdown text in a shell language (or none named), continuation lines joined."""
    blocks, current, language = [], None, ""
    for line in text.splitlines():
        if line.startswith("```"):
            if current is None:
                current, language = [], line[3:].strip()
            else:
                if language in ("", "bash", "sh", "shell", "console"):
                    blocks.append("\n".join(current).replace("\\\n", " "))
                current = None
        elif current is not None:
            current.append(line)
    return blocks


def committed_commands() -> list[tuple[str, str, list[str]]]:
    """(file, program, arguments) of every console-program command in the fenced shell blocks of results/*/RUN.md
    and models/checkpoints/README.md (commands with placeholders or shell variables left out)."""
    found = []
    for path in [*sorted(ROOT.glob("results/*/RUN.md")), ROOT / "models" / "checkpoints" / "README.md"]:
        for block in _shell_blocks(path.read_text()):
            for line in block.splitlines():
                line = line.replace("python -m veragmil_suite.scripts.bench", "veragmil-bench")
                lexer = shlex.shlex(line, posix=True, punctuation_chars=";|&")
                lexer.whitespace_split = True
                lexer.commenters = "#"
                tokens = list(lexer)
                for i, token in enumerate(tokens):
                    token = MODULE_TOKENS.get(token, token)
                    if token not in ENTRY_POINTS and token not in BENCHMARKS and token not in MODULE_PROGRAMS:
                        continue
                    words = []
                    for word in tokens[i + 1 :]:
                        if re.fullmatch(r"<[^<>]+>", word):  # a placeholder, "<the study above>"
                            words.append("...")
                            continue
                        if set(word) <= set(";|&") or re.fullmatch(r"\d*[<>]+.*", word):  # the command ends
                            break
                        words.append(word)
                    if not any("$" in w or "..." in w for w in words):
                        found.append((str(path.relative_to(ROOT)), token, words))
    return found


def _syntax_only(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """A copy of ``parser`` that checks names and counts of values, not the values (paths of another machine)."""
    import copy

    loose = copy.deepcopy(parser)
    for action in loose._actions:
        if isinstance(action.type, cli.ListOf):
            action.type = lambda text: [text]
        elif isinstance(action.type, cli.Kind):
            action.type = str
    return loose


def test_commands_committed_in_results_still_parse():
    commands = committed_commands()
    assert len(commands) > 20
    for where, program, argv in commands:
        try:
            _syntax_only(parser_of(program)).parse_args(argv)
        except SystemExit:
            pytest.fail(f"{where}: {program} {shlex.join(argv)} no longer parses")


# ---------------------------------------------------------------------------------------------------------------- #
# The handler                                                                                                      #
# ---------------------------------------------------------------------------------------------------------------- #


def test_ctrl_c_in_a_study_is_one_line_naming_the_resume_and_exit_130(tmp_path, monkeypatch, capsys):
    from veragmil_suite.scripts import study

    def interrupted(settings, **_):
        raise KeyboardInterrupt

    monkeypatch.setattr(study, "run_pipeline", interrupted)
    assert study.main(["--output-dir", str(tmp_path / "s")]) == 130
    err = capsys.readouterr().err
    said = [line for line in err.splitlines() if line.strip()]
    assert said == [f"veragmil-study: {study.INTERRUPTED}"] and "Traceback" not in err


@pytest.mark.parametrize(
    "error, line",
    [
        (OSError(28, "No space left on device", "/data/x.hdf5"), "prog: /data/x.hdf5: No space left on device"),
        (OSError(98, "Address already in use"), "prog: [Errno 98] Address already in use"),
        (cli.UsageError("give --output or --directory"), "prog: give --output or --directory"),
    ],
)
def test_the_handler_turns_an_expected_error_into_one_line_and_exit_2(error, line, capsys):
    def run(args):
        raise error

    main = cli.command(lambda: cli.Parser("prog"))(run)
    assert main([]) == 2
    assert capsys.readouterr().err.splitlines() == [line]


def test_output_to_a_reader_that_went_away_ends_quietly_with_sigpipes_status():
    """``veragmil-dataset-info file | head -1``: the reader closes the pipe before the program writes; no traceback,
    no message at exit, status 141 (128 + SIGPIPE), as a shell tool."""
    process = subprocess.Popen(
        [str(BIN / "veragmil-dataset-info"), str(ROOT / "demos" / "scoop.hdf5")],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    process.stdout.close()  # before the program has imported what it needs to print anything
    err = process.stderr.read().decode()
    assert process.wait(timeout=120) == 141, err
    assert "Traceback" not in err and "Broken pipe" not in err and "Exception ignored" not in err, err


def test_a_broken_pipe_that_is_not_the_output_keeps_its_traceback():
    """A socket's peer gone (a Ray worker, a VR page) is a failure to show, not a reader of the output gone."""

    def run(args):
        raise BrokenPipeError(32, "Broken pipe")

    with pytest.raises(BrokenPipeError):
        cli.command(lambda: cli.Parser("prog"))(run)([])


def test_the_handler_leaves_a_bug_its_traceback():
    def run(args):
        raise ZeroDivisionError("a bug")

    with pytest.raises(ZeroDivisionError):
        cli.command(lambda: cli.Parser("prog"))(run)([])
