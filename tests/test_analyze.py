"""clark analyze: latency statistics, the thesis's summary figures, loss, bad input, exit codes."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from clark_engine.analysis.latency import (
    AnalyzeError,
    LinkReport,
    analyze_folder,
    explain_deviation,
    format_text,
    summarize,
)
from clark_engine.cli import main
from clark_engine.errors import UsageError
from clark_engine.mission.compiler import compile_mission
from clark_engine.mission.validate import validate_path
from clark_engine.runtime.config import config_from_dict
from clark_engine.runtime.logbook import MESSAGE_LOG_COLUMNS, Logbook

ROOT = Path(__file__).resolve().parent.parent
HEADER = ",".join(MESSAGE_LOG_COLUMNS)
GPS_MS = 1_700_000_000_000


def row(
    direction: str,
    peer: str,
    counter: int | str,
    kind: str = "heartbeat",
    latency_ms: float | str = "",
    *,
    now_s: float = 1.0,
    detail: str = "",
) -> str:
    stamp = GPS_MS if kind else ""
    gps = "" if latency_ms in ("", "nan") else GPS_MS + int(latency_ms)
    return f"{direction},{now_s},{gps},{peer},{counter},40,{kind},{stamp},{latency_ms},{detail}"


def write_log(folder: Path, agent: str, rows: list[str]) -> Path:
    path = folder / f"{agent}.messages.csv"
    path.write_text("\n".join([HEADER, *rows]) + "\n", encoding="utf-8")
    return path


def write_header(folder: Path, agent: str, period_s: float) -> None:
    (folder / f"{agent}.mission.log").write_text(
        f"t=0.000 gps_ms=- INFO logbook.__init__: logbook opened: mission=m agent={agent} "
        f"loop_hz={1 / period_s!r} period_s={period_s!r} level=INFO\n"
        "t=0.100 gps_ms=- INFO runtime.tick: period_s=99 in a later line is ignored\n"
    )


def three_agents(folder: Path) -> Path:
    """a broadcasts 1-5 and sends 6 (two messages) to b; b sends 1-3 to a; c only listens.

    b gets 1, 2, 3 and both messages of 6 from a: latencies 100, 100, 100, 500 ms, and a
    Picture Data whose stamp is its capture time, not a latency. a gets all of b's: 700,
    800, 900 ms. c gets 1-5 from a with no GPS time (no latency). a rejects one packet
    claiming to be from b and one from nobody it can name.
    """
    write_log(
        folder,
        "a",
        [
            *(row("sent", "*", n) for n in range(1, 6)),
            row("sent", "b", 6, "agent_status"),
            row("sent", "b", 6, "picture_data"),
            row("received", "b", 1, "agent_status", 700),
            row("received", "b", 2, "agent_status", 800),
            row("received", "b", 3, "agent_status", 900),
            row("rejected", "b", "", "BadTag", detail="tag does not match"),
            row("rejected", "", "", "", detail="TruncatedPacket: 3 bytes"),
        ],
    )
    write_log(
        folder,
        "b",
        [
            row("received", "a", 1, "heartbeat", 100),
            row("received", "a", 2, "heartbeat", 100),
            row("received", "a", 3, "heartbeat", 100),
            row("received", "a", 6, "agent_status", 500),
            row("received", "a", 6, "picture_data", 90_000),  # capture time: no latency
            *(row("sent", "a", n, "agent_status") for n in range(1, 4)),
        ],
    )
    write_log(folder, "c", [row("received", "a", n) for n in range(1, 6)])
    for agent in "abc":
        write_header(folder, agent, 1.0)
    return folder


# ------------------------------------------------------------- statistics


def test_latency_statistics_per_link(tmp_path: Path) -> None:
    analysis = analyze_folder(three_agents(tmp_path))
    assert analysis.agents == ("a", "b", "c")
    assert [(link.sender, link.receiver) for link in analysis.links] == [
        ("a", "b"),
        ("a", "c"),
        ("b", "a"),
    ]
    ab, ac, ba = analysis.links
    assert (ab.messages, ab.mean_s, ab.std_s, ab.median_s, ab.min_s, ab.max_s) == (
        4,
        0.2,
        0.2,
        0.1,
        0.1,
        0.5,
    )
    assert (ba.messages, ba.mean_s, ba.std_s, ba.median_s, ba.min_s, ba.max_s) == (
        3,
        0.8,
        0.1,
        0.8,
        0.7,
        0.9,
    )
    assert (ac.messages, ac.mean_s, ac.std_s, ac.median_s) == (0, None, None, None)


def test_mean_of_means_sum_of_means_and_deviation(tmp_path: Path) -> None:
    analysis = analyze_folder(three_agents(tmp_path))
    assert analysis.mean_of_means_s == 0.5  # a -> c has no samples and is left out
    (pair,) = analysis.pairs
    assert (pair.first, pair.second, pair.sum_of_means_s, pair.deviation_s) == ("a", "b", 1.0, 0.0)
    assert analysis.sum_of_means_s == 1.0
    assert (analysis.period_s, analysis.period_source) == (1.0, "mission logs")
    assert analysis.deviation_s == 0.0
    given = analyze_folder(tmp_path, period_s=0.9)
    assert (given.period_s, given.period_source) == (0.9, "--period-s")
    assert given.deviation_s == 1.0 - 0.9


def test_loss_by_packet_counter_with_broadcasts(tmp_path: Path) -> None:
    ab, ac, ba = analyze_folder(three_agents(tmp_path)).links
    # a -> b: broadcasts 1-5 and packet 6 (two messages, one packet); b got 1, 2, 3, 6
    assert (ab.packets_sent, ab.packets_received, ab.packets_lost) == (6, 4, 2)
    assert ab.loss_ratio == 2 / 6
    assert (ac.packets_sent, ac.packets_received, ac.packets_lost, ac.loss_ratio) == (5, 5, 0, 0)
    assert (ba.packets_sent, ba.packets_received, ba.packets_lost, ba.rejected) == (3, 3, 0, 1)
    assert ab.rejected == 0


def test_a_missing_log_makes_its_side_unknown(tmp_path: Path) -> None:
    write_log(tmp_path, "b", [row("received", "a", 1, "heartbeat", 250), row("sent", "z", 4)])
    ab, bz = analyze_folder(tmp_path).links
    assert (ab.sender, ab.receiver, ab.packets_sent, ab.packets_received) == ("a", "b", None, 1)
    assert (ab.packets_lost, ab.loss_ratio, ab.rejected, ab.mean_s) == (None, None, 0, 0.25)
    assert (bz.packets_sent, bz.packets_received, bz.rejected) == (1, None, None)


def test_summary_reproduces_the_thesis_table_5_6() -> None:
    """Tables 5.3-5.5 give the link means; Table 5.6 the figures (rounded to 1 ms there)."""
    tables = {
        2: {(1, 2): 0.982, (2, 1): 0.131},
        3: {
            (1, 2): 0.824,
            (1, 3): 0.118,
            (2, 1): 0.264,
            (2, 3): 0.333,
            (3, 1): 0.997,
            (3, 2): 0.752,
        },
        4: {
            (1, 2): 0.726,
            (1, 3): 0.910,
            (1, 4): 0.806,
            (2, 1): 0.368,
            (2, 3): 0.228,
            (2, 4): 0.232,
            (3, 1): 0.197,
            (3, 2): 0.862,
            (3, 4): 0.942,
            (4, 1): 0.368,
            (4, 2): 1.006,
            (4, 3): 0.189,
        },
    }
    table_5_6 = {2: (0.556, 1.113, 0.113), 3: (0.547, 1.094, 0.094), 4: (0.569, 1.138, 0.138)}
    for agents, means in tables.items():
        links = [
            LinkReport(f"Agent{a}", f"Agent{b}", 60, m, None, None, None, None, *[None] * 5)
            for (a, b), m in means.items()
        ]
        pairs, mean_of_means, sum_of_means, deviation = summarize(links, 1.0)
        assert len(pairs) == agents * (agents - 1) // 2
        expected = table_5_6[agents]
        assert mean_of_means == pytest.approx(expected[0], abs=0.0015)
        assert sum_of_means == pytest.approx(expected[1], abs=0.0025)
        assert deviation == pytest.approx(expected[2], abs=0.0025)


def test_logs_written_by_the_logbook_are_analyzed(tmp_path: Path) -> None:
    mission = ROOT / "missions" / "cooperative_follow.yaml"
    result = validate_path(mission, mission.name)
    assert result.mission is not None
    configs = compile_mission(result.mission, ["mcs", "slash_a"])
    mcs = Logbook.to_folder(tmp_path, config_from_dict(json.loads(configs["mcs"])))
    rover = Logbook.to_folder(tmp_path, config_from_dict(json.loads(configs["slash_a"])))
    for i in range(1, 11):
        sent_ms = GPS_MS + 100 * i
        mcs.message("sent", i / 10, sent_ms, "*", i, 30, "heartbeat", sent_ms)
        if i != 4:  # lost
            rover.message("received", i / 10, sent_ms + 25, "mcs", i, 30, "heartbeat", sent_ms, 25)
        rover.message("sent", i / 10, sent_ms, "mcs", i, 50, "agent_status", sent_ms)
        mcs.message("received", i / 10, sent_ms + 75, "slash_a", i, 50, "agent_status", sent_ms, 75)
    mcs.close()
    rover.close()
    analysis = analyze_folder(tmp_path)
    to_rover, to_mcs = analysis.links
    assert (to_rover.messages, to_rover.mean_s, to_rover.packets_lost) == (9, 0.025, 1)
    assert (to_mcs.messages, to_mcs.mean_s, to_mcs.packets_lost) == (10, 0.075, 0)
    assert analysis.sum_of_means_s == 0.1
    assert (analysis.period_s, analysis.period_source) == (0.1, "mission logs")  # loop_hz 10
    assert analysis.problems == ()


# -------------------------------------------------------------- bad input


def test_malformed_rows_are_reported_with_file_and_line_and_skipped(tmp_path: Path) -> None:
    path = write_log(
        tmp_path,
        "b",
        [
            row("received", "a", 1, "heartbeat", 100),  # line 2
            "received,1.0,,a,2",  # 3
            row("lost", "a", 3),  # 4
            row("received", "a", "three"),  # 5
            "",  # 6: blank, ignored
            row("received", "a", 4, "heartbeat", "nan"),  # 7
            row("sent", "a", 5, "heartbeat", 10),  # 8
            row("received", "", 6),  # 9
            row("received", "a", -1),  # 10
            'received,1.0,,"a,7',  # 11: an open quote runs to the end of the file
            row("received", "a", 8, "heartbeat", 300),
        ],
    )
    analysis = analyze_folder(tmp_path)
    assert [(p.line, p.message) for p in analysis.problems] == [
        (3, "expected 10 fields, found 5"),
        (4, "direction is 'lost', not one of sent, received, rejected"),
        (5, "counter is 'three', not a whole number"),
        (7, "latency_ms is 'nan', not a finite number"),
        (8, "a sent row has a latency_ms"),
        (9, "a received row needs a peer"),
        (10, "counter is -1, below zero"),
        (11, "expected 10 fields, found 4"),
    ]
    assert all(p.file == str(path) for p in analysis.problems)
    assert analysis.problems[0].format_text() == (f"{path}:3: expected 10 fields, found 5; skipped")
    (link,) = analysis.links
    assert (link.messages, link.mean_s, analysis.rows) == (1, 0.1, 1)


def test_bad_bytes_spoil_only_their_row(tmp_path: Path) -> None:
    path = tmp_path / "b.messages.csv"
    good = row("received", "a", 1, "heartbeat", 100).encode()
    bad = row("received", "a\xff", 2, "heartbeat", 100).encode().replace(b"\xc3\xbf", b"\xff")
    path.write_bytes(b"\n".join([HEADER.encode(), good, bad, good.replace(b",1,", b",3,")]) + b"\n")
    analysis = analyze_folder(tmp_path)
    assert [(p.line, p.message) for p in analysis.problems] == [(3, "not UTF-8 text")]
    assert analysis.links[0].messages == 2


def test_a_file_that_is_not_a_message_log_is_skipped(tmp_path: Path) -> None:
    (tmp_path / "x.messages.csv").write_text("now_s,agent_id\n1,2\n")
    (tmp_path / "y.messages.csv").write_text("")
    write_log(tmp_path, "b", [row("received", "a", 1, "heartbeat", 100)])
    analysis = analyze_folder(tmp_path)
    assert analysis.agents == ("b",)
    assert [(Path(p.file).name, p.line) for p in analysis.problems] == [
        ("x.messages.csv", None),
        ("y.messages.csv", None),
    ]
    assert "not a message log (header is 'now_s,agent_id'" in analysis.problems[0].message
    assert "empty file" in analysis.problems[1].message


def test_folder_errors(tmp_path: Path) -> None:
    with pytest.raises(UsageError, match="no such folder"):
        analyze_folder(tmp_path / "missing")
    (tmp_path / "file").write_text("")
    with pytest.raises(UsageError, match="not a folder"):
        analyze_folder(tmp_path / "file")
    with pytest.raises(AnalyzeError, match="no message logs"):
        analyze_folder(tmp_path)
    (tmp_path / "x.messages.csv").write_text("garbage\n")
    with pytest.raises(AnalyzeError, match="none of its 1 message log"):
        analyze_folder(tmp_path)


def test_period_unknown_or_inconsistent(tmp_path: Path) -> None:
    write_log(tmp_path, "a", [row("received", "b", 1, "heartbeat", 100)])
    write_log(tmp_path, "b", [row("received", "a", 1, "heartbeat", 300)])
    analysis = analyze_folder(tmp_path)
    assert (analysis.sum_of_means_s, analysis.period_s, analysis.deviation_s) == (0.4, None, None)
    assert analysis.period_note == "no mission log header gives period_s; give --period-s"
    write_header(tmp_path, "a", 0.1)
    write_header(tmp_path, "b", 0.2)
    analysis = analyze_folder(tmp_path)
    assert analysis.deviation_s is None
    assert analysis.period_note == (
        "the mission logs disagree on the period (a 0.1 s, b 0.2 s); give --period-s"
    )
    assert analyze_folder(tmp_path, period_s=0.5).deviation_s == pytest.approx(-0.1)


def test_text_report_is_deterministic_and_complete(tmp_path: Path) -> None:
    analysis = analyze_folder(three_agents(tmp_path))
    report = format_text(analysis)
    assert report == format_text(analyze_folder(tmp_path))
    assert "a -> b         4  0.200  0.200   0.100  0.100  0.500" in report
    assert "a -> c         0      -      -       -      -      -" in report
    assert "a <-> b         1.000      0.000" in report
    assert "mean of means         0.500 s" in report
    assert "deviation from ideal  0.000 s" in report
    assert "a -> b     6         4     2  33.3%         0" in report


# -------------------------------------------------------------------- CLI


def test_cli_text_and_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    three_agents(tmp_path)
    assert main(["analyze", str(tmp_path)]) == 0
    captured = capsys.readouterr()
    assert "Message latency by link" in captured.out
    assert captured.err == ""
    assert main(["analyze", str(tmp_path), "--format", "json", "--period-s", "0.5"]) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload["agents"] == ["a", "b", "c"]
    assert payload["links"][0] == {
        "sender": "a",
        "receiver": "b",
        "messages": 4,
        "mean_s": 0.2,
        "std_s": 0.2,
        "median_s": 0.1,
        "min_s": 0.1,
        "max_s": 0.5,
        "packets_sent": 6,
        "packets_received": 4,
        "packets_lost": 2,
        "loss_ratio": 2 / 6,
        "rejected": 0,
    }
    assert payload["links"][1]["mean_s"] is None
    assert (payload["period_s"], payload["period_source"], payload["deviation_s"]) == (
        0.5,
        "--period-s",
        0.5,
    )
    assert payload["pairs"] == [
        {"first": "a", "second": "b", "sum_of_means_s": 1.0, "deviation_s": 0.5}
    ]


def test_cli_reports_skipped_rows_on_stderr_and_exits_0(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write_log(tmp_path, "b", [row("received", "a", 1, "heartbeat", 100), "junk"])
    assert main(["analyze", str(tmp_path), "--format", "json"]) == 0
    captured = capsys.readouterr()
    assert captured.err == (
        f"clark analyze: warning: {path}:3: expected 10 fields, found 1; skipped\n"
    )
    assert json.loads(captured.out)["problems"] == [
        {"file": str(path), "line": 3, "message": "expected 10 fields, found 1"}
    ]


@pytest.mark.parametrize(
    ("setup", "args", "code", "message"),
    [
        ("missing", [], 2, "no such folder"),
        ("file", [], 2, "not a folder"),
        ("empty", [], 1, "no message logs"),
        ("garbage", [], 1, "could be read"),
        ("empty", ["--period-s", "0"], 2, "not a positive number of seconds"),
        ("empty", ["--period-s", "nan"], 2, "not a positive number of seconds"),
        ("empty", ["--format", "xml"], 2, "invalid choice"),
    ],
)
def test_cli_exit_codes(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    setup: str,
    args: list[str],
    code: int,
    message: str,
) -> None:
    folder = tmp_path / "logs"
    if setup == "file":
        folder.write_text("")
    elif setup != "missing":
        folder.mkdir()
    if setup == "garbage":
        (folder / "a.messages.csv").write_bytes(b"\x00\xff\xfe garbage\n")
    assert run(["analyze", str(folder), *args]) == code
    err = capsys.readouterr().err
    assert message in err
    assert "Traceback" not in err


def run(argv: list[str]) -> int:
    """main's exit code, including argparse's usage errors (which exit through SystemExit)."""
    try:
        return main(argv)
    except SystemExit as exc:
        return int(exc.code or 0)


def test_no_messages_at_all_is_a_valid_empty_report(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    write_log(tmp_path, "a", [])
    assert main(["analyze", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "no messages were sent or received" in out
    assert "mean of means         - s" in out


def test_the_example_in_the_docs_is_real_output(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "logs").mkdir()
    three_agents(tmp_path / "logs")
    monkeypatch.chdir(tmp_path)
    report = format_text(analyze_folder(Path("logs")))
    docs = (ROOT / "docs" / "logs.md").read_text(encoding="utf-8")
    assert f"$ clark analyze logs\n{report}```" in docs


# ------------------------------------------------------------- the report's explanation


def test_explain_deviation_says_what_it_is_and_how_to_read_it(tmp_path: Path) -> None:
    """The dry run's Links section explains "deviation from ideal" with the run's figures."""
    text = explain_deviation(analyze_folder(three_agents(tmp_path)))
    assert "**Deviation from ideal**" in text
    assert "sum of means (1.000 s) minus the sample period (1.0 s, from mission logs)" in text
    assert "= 0.000 s" in text
    # Why the ideal is one period in the thesis, and near minus one period here.
    assert "one loop period" in text and "near minus one period" in text
    assert "docs/logs.md" in text


def test_explain_deviation_without_a_period_says_how_to_get_one(tmp_path: Path) -> None:
    three_agents(tmp_path)
    for agent in "abc":
        (tmp_path / f"{agent}.mission.log").unlink()
    text = explain_deviation(analyze_folder(tmp_path))
    assert "not computed" in text and "--period-s" in text


def test_links_between_clocks_days_apart_are_refused_not_averaged(tmp_path: Path) -> None:
    """A station on the system clock and a vehicle on a simulated autopilot's GPS time
    (331 days apart, as in a --realtime rehearsal): latencies of +-28 million seconds are
    no latencies. The link's loss still counts; its latency is refused, saying why."""
    days_331_ms = 331 * 86_400_000
    write_log(
        tmp_path,
        "mcs",
        [
            *(row("sent", "*", n) for n in range(1, 4)),
            *(row("received", "v", n, "agent_status", days_331_ms + 30) for n in range(1, 4)),
        ],
    )
    write_log(
        tmp_path,
        "v",
        [
            *(row("sent", "*", n, "agent_status") for n in range(1, 4)),
            *(row("received", "mcs", n, "heartbeat", -days_331_ms + 20) for n in range(1, 3)),
        ],
    )
    analysis = analyze_folder(tmp_path)
    links = {(link.sender, link.receiver): link for link in analysis.links}
    assert links[("v", "mcs")].mean_s is None and links[("mcs", "v")].mean_s is None
    assert links[("mcs", "v")].packets_lost == 1  # loss is by counter: it stands
    assert analysis.mean_of_means_s is None
    problems = [p for p in analysis.problems if "clocks" in p.message]
    assert [p.file for p in problems] == ["v.messages.csv", "mcs.messages.csv"]
    assert all("331 days apart" in p.message and "one time base" in p.message for p in problems)
    assert "clocks are 331 days apart" in format_text(analysis)


def test_a_wall_clock_dry_run_stamps_every_log_on_one_time_base(tmp_path: Path) -> None:
    """--realtime with MAVLink ports: the simulated autopilots give the wall clock's GPS
    time, and the station is anchored to it (before: the station stamped 2026-01-01 and
    every latency between them read as +-days)."""
    from clark_engine.dryrun.engine import DryRun

    path = ROOT / "missions" / "cooperative_follow.yaml"
    mission = validate_path(path).mission
    assert mission is not None
    logs = tmp_path / "logs"
    run = DryRun(mission, path, seed=1, until_s=14.0, log_dir=logs, speed=1.0, wall_clock=True)
    run.run()
    analysis = analyze_folder(logs)
    assert not [p for p in analysis.problems if p.clocks], analysis.problems
    assert any(link.messages for link in analysis.links)
    assert all(abs(link.mean_s or 0.0) < 1.0 for link in analysis.links)
