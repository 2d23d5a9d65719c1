"""The one error boundary of ``asvtwin``: bad input is one line on stderr and exit 2,
never a traceback and never on stdout; a closed pipe ends quietly."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import pytest

from asvtwin.cli import EXIT_BROKEN_PIPE, EXIT_ERROR, build_parser, main
from asvtwin.errors import SourceError

ROOT = Path(__file__).resolve().parents[2]


def _one_line_error(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert "Traceback" not in err
    assert lines, "nothing on stderr"
    assert "error:" in lines[-1]
    return lines[-1]


@pytest.fixture
def existing_file(tmp_path: Path) -> Path:
    f = tmp_path / "taken"
    f.write_text("not a folder\n")
    return f


# (argv, a phrase the one-line message must contain); {file} is an existing plain file
CASES = [
    (["sim", "--out", "{file}"], "File exists"),
    (["sim", "--dt", "100", "--no-plot", "--out", "{dir}"], "stability limit"),
    (["sim", "--surge-fraction", "3"], "fraction in (0, 1]"),
    (["sim", "--yaw-fraction", "0"], "fraction in (0, 1]"),
    (["sim", "--surge-fraction", "nan"], "finite"),
    (["sim", "--manoeuvre", "zigzag", "--switch-deg", "0", "--out", "{dir}"],
     "must be in (0, 90) [deg]"),
    (["sim", "--manoeuvre", "figure8"], "invalid choice"),
    (["sim", "--vessel", "titanic"], "invalid choice"),
    (["sim", "--scene", "{dir}/no_such_scene.yaml", "--out", "{dir}"], "no_such_scene"),
    (["psf", "demo", "--backend", "foo"], "invalid choice"),
    (["psf", "demo", "--duration", "-5"], "expected a number > 0"),
    (["weather", "show", "--step", "0"], "expected a number > 0"),
    (["weather", "show", "--file", "{dir}/missing.json"], "missing.json"),
    (["observer", "report", "--vessel", "titanic"], "invalid choice"),
    (["figures", "tracking", "--out", "{file}"], "File exists"),
]


@pytest.mark.parametrize("argv,phrase", CASES, ids=[" ".join(c[0]) for c in CASES])
def test_bad_input_is_one_line_on_stderr_exit_2(argv, phrase, tmp_path, existing_file,
                                               capsys):
    argv = [a.format(file=existing_file, dir=tmp_path) for a in argv]
    try:
        code = main(argv)
    except SystemExit as e:  # argparse's own usage errors also exit 2
        code = e.code
    out, err = capsys.readouterr()
    assert code == EXIT_ERROR
    line = _one_line_error(err)
    assert phrase in line
    assert "error" not in out.lower()  # errors never mix into stdout


def test_boundary_message_has_command_and_hint(existing_file, capsys):
    assert main(["sim", "--out", str(existing_file)]) == EXIT_ERROR
    err = capsys.readouterr().err.strip()
    assert err.startswith("asvtwin sim: error: File exists")
    assert "(hint: " in err and len(err.splitlines()) == 1


def test_verbose_after_the_subcommand_shows_the_traceback(existing_file, capsys):
    assert main(["sim", "-v", "--out", str(existing_file)]) == EXIT_ERROR
    err = capsys.readouterr().err
    assert err.splitlines()[0].startswith("asvtwin sim: error:")
    assert "Traceback" in err and "FileExistsError" in err
    # and -v before the sub-command still counts
    assert build_parser().parse_args(["-vv", "sim"]).verbose == 2
    assert build_parser().parse_args(["sim", "-v"]).verbose == 1


def test_asvtwin_error_from_a_handler_and_broken_pipe(monkeypatch, capsys):
    from asvtwin.cli import sim

    def raises(exc):
        def handler(_args):
            raise exc
        return handler

    monkeypatch.setattr(sim, "_run", raises(SourceError("feed tcp://x:1 closed\nretry")))
    parser_main = main  # the handler is looked up at parse time: rebuild
    assert parser_main(["sim"]) == EXIT_ERROR
    out, err = capsys.readouterr()
    assert out == "" and err.strip() == ("asvtwin sim: error: feed tcp://x:1 closed; retry "
                                         "(hint: see 'asvtwin sim --help'; -v shows the "
                                         "traceback)")
    monkeypatch.setattr(sim, "_run", raises(BrokenPipeError(32, "Broken pipe")))
    assert main(["sim"]) == EXIT_BROKEN_PIPE
    assert capsys.readouterr() == ("", "")


def test_a_bug_keeps_its_traceback(monkeypatch):
    from asvtwin.cli import sim

    def bug(_args):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(sim, "_run", bug)
    with pytest.raises(ZeroDivisionError):
        main(["sim"])


def test_json_into_a_closed_pipe_ends_quietly():
    # a real pipe: the reader takes one line and closes it
    cmd = (f"{sys.executable} -m asvtwin weather show --json --hours 48 --step 0.05 "
           "| head -n 1")
    proc = subprocess.run(["sh", "-c", cmd], capture_output=True, text=True, cwd=ROOT,
                          timeout=120, check=False)
    assert proc.stderr == ""
    row = json.loads(proc.stdout)
    assert "wind_speed_m_s" in row


def _option(argv_prefix, flag):
    parser = build_parser()
    for name in argv_prefix:
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        parser = sub.choices[name]
    return parser._option_string_actions[flag]


@pytest.mark.parametrize("prefix,flag,expected", [
    (("sim",), "--vessel", {"cybership2", "cybership2_full_scale"}),
    (("sim",), "--manoeuvre", {"turning_circle", "zigzag", "thrust_step"}),
    (("psf", "demo"), "--backend", {"auto", "acados", "casadi-ipopt", "casadi-fatrop"}),
    (("observer", "report"), "--vessel", {"cybership2", "cybership2_full_scale"}),
])
def test_enumerated_options_use_choices(prefix, flag, expected):
    assert set(_option(prefix, flag).choices) == expected


@pytest.mark.parametrize("prefix", [("sim",), ("psf", "demo"), ("observer", "report"),
                                    ("figures", "tracking")])
def test_out_defaults_to_out_slash_command(prefix):
    default = Path(str(_option(prefix, "--out").default or "out/figures/tracking"))
    assert default.parts[0] == "out" and default.parts[1] == prefix[0]


def test_help_has_no_rest_markup():
    """``--help`` is read in a terminal: no reST double backticks or roles."""
    def walk(parser):
        yield parser
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for sub in action.choices.values():
                    yield from walk(sub)

    for parser in walk(build_parser()):
        text = parser.format_help()
        assert "``" not in text and ":func:" not in text and ":class:" not in text, \
            parser.prog


def test_psf_backend_choices_match_the_control_package():
    from asvtwin.cli.argtypes import PSF_BACKENDS
    from asvtwin.control import BACKENDS

    assert PSF_BACKENDS == ("auto", *BACKENDS)


def test_controller_choices_match_the_scenario_schema():
    from asvtwin.cli.argtypes import CONTROLLERS as CLI_CONTROLLERS
    from asvtwin.scenarios import CONTROLLERS

    assert CLI_CONTROLLERS == CONTROLLERS


def _every_option():
    def walk(parser):
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for sub in action.choices.values():
                    yield from walk(sub)
            elif action.option_strings:
                yield parser.prog, action

    return list(walk(build_parser()))


def test_every_backend_option_of_every_command_has_choices():
    missing = [f"{prog} {a.option_strings[0]}" for prog, a in _every_option()
               if "backend" in a.option_strings[-1] and not a.choices]
    assert missing == []


def test_every_out_default_of_every_command_is_under_out():
    """One convention: files go to out/<command> unless --out says otherwise (a None
    default means "write nothing" or "stdout" and is allowed)."""
    wrong = [f"{prog} --out default {a.default}" for prog, a in _every_option()
             if "--out" in a.option_strings and a.default is not None
             and Path(str(a.default)).parts[:1] != ("out",)]
    assert wrong == []
