"""The CLI convention of docs/cli.md, checked on every command by walking the command tree.

A new command or option that breaks a rule fails here: help and an example for every command,
a metavar for every option that takes a value and none for flags, one name (and one metavar) per
concept, several values after one option or the option repeated, the one default-vessel rule,
workspaces that reading commands never create, output folders that must exist, one ``error:``
line with exit 2 for bad input, and one line saying why an input loaded nothing.
"""

from __future__ import annotations

import json
import shlex
from pathlib import Path

import pytest
import typer.main
from pipelines.cli import app, main
from cli_walk import example_lines, walk_commands

REPO = Path(__file__).resolve().parents[1]
COMMANDS = dict(walk_commands(typer.main.get_command(app)))

#: One name per concept: the names below must not be visible options of any command.
RETIRED_NAMES = {"--operator": "--profile", "--workdir": "--out", "--every": "--step-h"}
#: Options that mean the same everywhere carry the same metavar.
SAME_METAVAR = {"--db": "FILE", "--weather": "FILE|DIR", "--vessel": "NAME|FILE", "--profile": "NAME|FILE",
                "--speed-loss": "bowditch|aertssen|khokhlov|kwon|none", "--task-runner": "sequential|dask[:ADDRESS]",
                "--depart": "ISO", "--start": "ISO", "--end": "ISO", "--now": "ISO", "--lane": "ID",
                "--window-h": "H", "--step-h": "H", "--safety": None, "--exports": "proposed|all|none", "--max-detail": "N", "--seed": "N", "--days": "N"}
#: Commands that write data into the workspace and so may create it; every other --db must exist.
CREATES_WORKSPACE = {"workspace", "ingest-ais", "weather load", "weather fetch"}


def _visible_options(cmd):
    return [p for p in cmd.params if p.param_type_name == "option" and not p.hidden]


def test_every_command_is_walked():
    assert {"route", "audit", "deviate", "nightly", "schedule", "ingest-ais", "lanes", "weather join", "weather fetch",
            "weather info", "weather load", "weather exceedance", "report", "scenario", "demo", "workspace"} <= set(COMMANDS)


@pytest.mark.parametrize("path", sorted(COMMANDS))
def test_help_example_and_conventions_link(path):
    cmd = COMMANDS[path]
    ctx = typer.main.get_command(app).make_context("stormlane", [path.split()[0]], resilient_parsing=True)
    text = cmd.get_help(ctx)
    assert "Example" in text, f"{path}: no example in --help"
    assert "docs/cli.md" in text, f"{path}: --help does not point to the conventions"
    examples = example_lines(text, path)
    assert examples, f"{path}: the example does not start with `stormlane {path}`"
    for line in examples:  # every example parses with the command's own parser
        words = shlex.split(line)[1 + len(path.split()):]
        cmd.make_context(path, words, resilient_parsing=True)


@pytest.mark.parametrize("path", sorted(COMMANDS))
def test_options_have_help_metavars_and_flags_show_as_flags(path):
    cmd = COMMANDS[path]
    ctx = cmd.make_context(path, [], resilient_parsing=True)
    for p in cmd.params:
        if p.param_type_name == "argument":
            assert p.metavar and p.metavar.isupper() or "|" in (p.metavar or ""), f"{path} {p.name}: argument without a metavar"
            continue
        if p.hidden:
            continue
        assert p.help, f"{path} {p.opts}: option without help"
        record = p.get_help_record(ctx)[0]
        if p.is_flag:
            assert record == p.opts[0] or record.startswith(f"{p.opts[0]} /"), f"{path}: flag shown as {record!r}"
        else:
            assert p.metavar and "<" not in p.metavar, f"{path} {p.opts}: no explicit metavar ({record!r})"
        for name in p.opts:
            assert name not in RETIRED_NAMES, f"{path}: {name} is spelled {RETIRED_NAMES[name]} everywhere"


def test_one_metavar_per_concept():
    seen: dict[str, set] = {}
    for path, cmd in COMMANDS.items():
        for p in _visible_options(cmd):
            seen.setdefault(p.opts[0], set()).add(p.metavar)
    for name, metavar in SAME_METAVAR.items():
        if metavar is not None:
            assert seen.get(name, {metavar}) == {metavar}, f"{name}: metavars {seen.get(name)}"
        else:
            assert len(seen.get(name, {None})) == 1, f"{name}: metavars {seen.get(name)}"


def test_speed_loss_choices_are_the_models():
    from pipelines.commands._common import SPEED_LOSS_MODELS
    from pipelines.commands.weather import PRODUCTS
    from routing.speed_loss import MODELS
    from weather.io.cmems import DATASETS

    assert SPEED_LOSS_MODELS == MODELS
    assert set(PRODUCTS) == set(DATASETS) | {"era5-wind"}


def _multi_options():
    for path, cmd in sorted(COMMANDS.items()):
        for p in _visible_options(cmd):
            if p.multiple:
                yield path, p.opts[0]


@pytest.mark.parametrize(("path", "option"), list(_multi_options()))
def test_several_values_after_one_option_or_repeated(path, option):
    cmd = COMMANDS[path]
    name = next(p.name for p in cmd.params if p.opts and p.opts[0] == option)
    spread = cmd.make_context(path, [option, "a", "b", "--json"] if any(p.opts[0] == "--json" for p in _visible_options(cmd))
                              else [option, "a", "b"], resilient_parsing=True)
    repeated = cmd.make_context(path, [option, "a", option, "b"], resilient_parsing=True)
    assert [str(v) for v in spread.params[name]] == [str(v) for v in repeated.params[name]] == ["a", "b"]
    args = [p for p in cmd.params if p.param_type_name == "argument"]
    assert not args, f"{path}: a multi-valued option would swallow the arguments {args}"


def test_the_multi_valued_options_are_the_documented_ones():
    assert set(_multi_options()) == {
        ("audit", "--weather"), ("deviate", "--weather"), ("route", "--weather"), ("nightly", "--weather"),
        ("schedule", "--weather"), ("nightly", "--lane"), ("schedule", "--lane"), ("lanes", "--ports"),
        ("weather join", "--depart"), ("learn performance", "--weather"), ("learn performance", "--class"),
    }


@pytest.mark.parametrize("path", sorted(p for p, c in COMMANDS.items() if any(o.opts[0] == "--db" for o in c.params if o.opts)))
def test_workspace_rules(path, tmp_path, capsys):
    """--db in a missing folder is an error for every command; a missing workspace is an error for
    every command that reads one, and nothing is created."""
    cmd = COMMANDS[path]
    db = next(p for p in cmd.params if p.opts and p.opts[0] == "--db")
    creates = db.callback.__name__ == "_db_new_ok" if hasattr(db.callback, "__name__") else None
    assert creates == (path in CREATES_WORKSPACE), f"{path}: --db {'creates' if creates else 'must exist'}"
    from pipelines.commands._common import PathOptionError

    with pytest.raises(PathOptionError, match=r"folder .*missing.* does not exist"):
        cmd.make_context(path, ["--db", str(tmp_path / "missing" / "x.duckdb")])
    assert not (tmp_path / "missing").exists()
    if not creates:
        with pytest.raises(PathOptionError, match=r"workspace .*typo\.duckdb does not exist"):
            cmd.make_context(path, ["--db", str(tmp_path / "typo.duckdb")])
        assert not (tmp_path / "typo.duckdb").exists()


def _one_error_line(capsys, argv) -> str:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    out, err = capsys.readouterr()
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert err.startswith("error: ")
    return err.strip()


def test_the_issue_cases(tmp_path, capsys):
    line = _one_error_line(capsys, ["weather", "join", "--db", str(tmp_path / "typo.duckdb"), "--depart", "2025-01-14"])
    assert "typo.duckdb does not exist" in line and not (tmp_path / "typo.duckdb").exists()
    line = _one_error_line(capsys, ["workspace", "--db", str(tmp_path / "missing" / "dir" / "x.duckdb")])
    assert line == f"error: workspace {tmp_path / 'missing' / 'dir' / 'x.duckdb'}: folder {tmp_path / 'missing' / 'dir'} does not exist"
    assert not (tmp_path / "missing").exists()
    binary = tmp_path / "model.json"
    binary.write_bytes(bytes(range(256)) * 4)
    assert "not a report model (binary content" in _one_error_line(capsys, ["report", "--model", str(binary), "--out", str(tmp_path / "r.html")])
    malformed = tmp_path / "bad.json"
    malformed.write_text(json.dumps({"__class__": "NightlyReport", "title": "x", "departures": 5}))
    assert "report model JSON is malformed" in _one_error_line(capsys, ["report", "--model", str(malformed), "--out", str(tmp_path / "r.html")])


def test_version(capsys):
    from importlib.metadata import version

    main(["--version"])  # typer.Exit(0): main returns normally
    assert capsys.readouterr().out.strip() == f"stormlane {version('stormlane')}"


def test_default_vessel_without_ais_is_the_container_feeder(capsys):
    """route has no AIS ship: the one rule gives container-feeder (docs/configuration.md)."""
    main(["route", "--from", "10,0", "--to", "10,1", "--depart", "2025-01-14T00:00Z", "--mesh-deg", "0.25", "--ignore-land",
          "--edges", "8", "--json"])
    out = json.loads(capsys.readouterr().out)
    from pipelines.config import load_vessel

    feeder = load_vessel("container-feeder")
    # calm water, no land: the time-optimal route is sailed at the feeder's service speed
    assert out["optimal"]["time_h"] == pytest.approx(out["optimal"]["dist_nmi"] / feeder.speed_kn, rel=1e-6)


def test_an_input_that_loads_nothing_says_why(tmp_path, capsys, shared_data):
    sample = shared_data / "ais" / "nmea" / "pyais_nmea_data_sample.nmea"
    if not sample.exists():
        pytest.skip(f"real data file missing: {sample}")
    db = tmp_path / "ws.duckdb"
    main(["ingest-ais", str(sample), "--db", str(db), "--json"])
    out, err = capsys.readouterr()
    assert json.loads(out)["loaded"] == 0
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"warning: {sample}: nothing loaded: 761 of its 896 messages have no time")
    assert "$PGHP" in lines[0]
    noise = tmp_path / "noise.bin"
    noise.write_bytes(bytes((i * 37 + 11) % 256 for i in range(5000)))
    main(["ingest-ais", str(noise), "--format", "nmea", "--db", str(db)])
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "nothing loaded" in lines[0] and "are not AIS sentences" in lines[0], err


def test_a_file_of_times_in_another_layout_says_which_layout_it_needs(tmp_path, capsys):
    """Its rows have times, in a layout the format does not read: "have no time" alone read as
    if the column were empty (found by the acceptance sweep)."""
    zulu = tmp_path / "zulu.csv"
    zulu.write_text("MMSI,BaseDateTime,LAT,LON,SOG,COG,Heading\n"
                    "367752440,2023-01-11T00:00:00Z,43.07917,-70.75733,0.0,360.0,95.0\n"
                    "367752440,2023-01-11T00:01:00Z,43.07917,-70.75733,0.0,360.0,95.0\n")
    main(["ingest-ais", str(zulu), "--db", str(tmp_path / "ws.duckdb"), "--json"])
    out, err = capsys.readouterr()
    assert json.loads(out)["reasons"] == {"bad_time": 2}
    assert err == (f"warning: {zulu}: nothing loaded: 2 of its 2 rows have no time readable in the noaa layout "
                   "('2025-01-31T23:59:00' or '2025-01-31 23:59:00', UTC) within 1990-2099\n")


def test_files_skipped_in_a_folder_are_warning_lines_said_once(tmp_path, capsys, monkeypatch):
    """A folder's hidden, empty and dangling files: one `warning:` line each, also on a terminal
    (where the progress bar's byte count walked the folder a second time: every line came twice,
    and none had the `warning:` prefix)."""
    import pipelines.commands.ingest as ingest_cmd

    folder = tmp_path / "ais"
    folder.mkdir()
    (folder / "a.csv").write_text("MMSI,BaseDateTime,LAT,LON,SOG,COG,Heading\n"
                                  "367752440,2023-01-11T00:00:00,43.07917,-70.75733,0.0,360.0,95.0\n")
    (folder / "empty.csv").write_text("")
    (folder / ".hidden.csv").write_text("x")
    (folder / "gone.csv").symlink_to(tmp_path / "missing.csv")
    monkeypatch.setattr(ingest_cmd, "interactive", lambda: True)  # the progress bar's path, as on a terminal
    main(["ingest-ais", str(folder), "--db", str(tmp_path / "ws.duckdb")])
    err = [line for line in capsys.readouterr().err.splitlines() if "skipped" in line]
    assert sorted(err) == sorted(f"warning: {folder / f}: {why} in {folder}, skipped"
                                 for f, why in ((".hidden.csv", "hidden file"), ("empty.csv", "empty file"),
                                                ("gone.csv", "link to nothing")))


def test_cli_doc_lists_every_command():
    text = (REPO / "docs" / "cli.md").read_text(encoding="utf-8")
    for path in COMMANDS:
        assert f"`stormlane {path}" in text, f"docs/cli.md does not list `stormlane {path}`"


#: Options naming a path the command writes (or creates): each checks its folder at parse time.
OUTPUT_OPTIONS = {"--out", "--report", "--geojson", "--screenshot", "--spool", "--cache", "--db"}


@pytest.mark.parametrize("path", sorted(COMMANDS))
def test_every_output_path_checks_its_folder(path, tmp_path):
    from pipelines.commands._common import PathOptionError

    cmd = COMMANDS[path]
    for p in _visible_options(cmd):
        if p.opts[0] in OUTPUT_OPTIONS:
            assert p.callback is not None, f"{path} {p.opts[0]}: no folder check"
            with pytest.raises(PathOptionError, match="does not exist"):  # checked first, as given first
                cmd.make_context(path, [p.opts[0], str(tmp_path / "missing" / "x")])


def test_help_imports_no_numeric_stack():
    """`stormlane --help` must start fast and light (issue 18: <= 0.5 s): the command modules import
    numpy, pandas, xarray and the kernels inside the commands, never at module level. A command
    module importing pandas at the top had made --help 0.5 s and 116 MB (from 0.15 s and 18 MB)."""
    import subprocess
    import sys

    code = ("import sys, pipelines.cli; "
            "print(' '.join(sorted(m for m in ('numpy', 'pandas', 'xarray', 'duckdb', 'numba', 'sklearn', 'prefect') "
            "if m in sys.modules)))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "", f"importing the CLI loads {out}"
