"""The jsonl importer (wiretape convert X.jsonl OUT --from jsonl): every bad
line is one clean error naming the file, the line and the field, with the
CLI's exit code for a damaged session file (1), never a traceback; and every
file of the fuzz corpus either converts or fails that way."""

import importlib.util
import json
from pathlib import Path

import pytest

import wiretape
from wiretape import cli
from wiretape.tools import convert as convert_module

ROOT = Path(__file__).resolve().parents[3]
CORPUS = ROOT / "fuzz" / "corpus" / "jsonl_import_fuzz"

HEADER = json.dumps({"header": {"port_type": "serial", "capture": "client"}})
GOOD = '{"t_ns":5,"kind":"rx","data_hex":"41"}'
MAX_T_NS = wiretape._core.MAX_RECORD_T_NS  # the format's bound, about 136 years
RANGE = f"t_ns: out of range 0..{MAX_T_NS}"


def run_cli(capsys, *argv):
    code = cli.main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


# (lines after the header, the bad line's number, what the message must say)
BAD_FILES = {
    "not_json": ([GOOD, '{"t_ns": 1,'], 3, "not JSON"),
    "deeply_nested": ([GOOD, "[" * 5000], 3, "not JSON: nested too deeply"),
    "a_list": ([GOOD, "[1, 2]"], 3, "expected a JSON object, got an array"),
    "a_number": (["7"], 2, "expected a JSON object, got the number 7"),
    "a_string": (['"rx"'], 2, "expected a JSON object, got the string 'rx'"),
    "null": (["null"], 2, "expected a JSON object, got null"),
    "missing_t_ns": (['{"kind":"rx","data_hex":"41"}'], 2, "t_ns: missing"),
    "missing_kind": (['{"t_ns":1,"data_hex":"41"}'], 2, "kind: missing"),
    "missing_data_hex": (['{"t_ns":1,"kind":"tx"}'], 2, "data_hex: missing"),
    "t_ns_string": (['{"t_ns":"5","kind":"rx","data_hex":"41"}'], 2,
                    "t_ns: expected a whole number of nanoseconds, got the string '5'"),
    "t_ns_bool": (['{"t_ns":true,"kind":"rx","data_hex":"41"}'], 2,
                  "t_ns: expected a whole number of nanoseconds, got a boolean"),
    "t_ns_float": (['{"t_ns":1.5,"kind":"rx","data_hex":"41"}'], 2,
                   "t_ns: expected a whole number of nanoseconds, got the number 1.5"),
    "t_ns_float_whole": (['{"t_ns":2.0,"kind":"rx","data_hex":"41"}'], 2,
                         "t_ns: expected a whole number of nanoseconds"),
    "t_ns_exponent": (['{"t_ns":1e1000,"kind":"rx","data_hex":"41"}'], 2,
                      "t_ns: expected a whole number of nanoseconds, got the number inf"),
    "t_ns_negative": (['{"t_ns":-1,"kind":"rx","data_hex":"41"}'], 2,
                      f"{RANGE}: -1"),
    "t_ns_past_2_64": (['{"t_ns":18446744073709551616,"kind":"rx","data_hex":"41"}'], 2,
                       f"{RANGE}: 18446744073709551616"),
    "t_ns_past_the_bound": (['{"t_ns":%d,"kind":"rx","data_hex":"41"}' % (MAX_T_NS + 1)], 2,
                            f"{RANGE}: {MAX_T_NS + 1}"),
    "event_nested_past_the_limit": (
        ['{"t_ns":1,"kind":"settings","event":{"a":' + "[" * 70 + "]" * 70 + "}}"], 2,
        'event: settings event: member "a" is a list; event members are bool, int or str'),
    # Event members are checked against the record-kind table (event_payload).
    "event_unknown_member": (['{"t_ns":1,"kind":"settings","event":{"baud":9600,"speed":1}}'], 2,
                             'event: settings event: unknown member "speed"'),
    "event_member_type": (['{"t_ns":1,"kind":"settings","event":{"baud":"fast"}}'], 2,
                          'event: settings event: member "baud" must be an integer, not a string'),
    "event_member_missing": (['{"t_ns":1,"kind":"fault","event":{"kind":"drop"}}'], 2,
                             'event: fault event: required member "where" is missing'),
    "t_ns_10_to_1000": (['{"t_ns":1' + "0" * 1000 + ',"kind":"rx","data_hex":"41"}'], 2,
                        f"{RANGE}: a number of 1001 digits"),
    "t_ns_too_many_digits": (['{"t_ns":' + "9" * 5000 + ',"kind":"rx","data_hex":"41"}'], 2,
                             "not JSON"),
    "kind_unknown": (['{"t_ns":1,"kind":"rxx","data_hex":"41"}'], 2,
                     "kind: unknown record kind 'rxx': one of rx, tx"),
    "kind_wrong_type": (['{"t_ns":1,"kind":[1],"data_hex":"41"}'], 2,
                        "kind: expected a record kind name, got an array"),
    "kind_code_range": (['{"t_ns":1,"kind_code":256,"data_hex":"41"}'], 2,
                        "kind_code: expected a record kind code 0..255, got the number 256"),
    "kind_code_huge": (['{"t_ns":1,"kind_code":' + "9" * 40 + ',"data_hex":"41"}'], 2,
                       "kind_code: expected a record kind code 0..255"),
    "kind_negative": (['{"t_ns":1,"kind":-3,"data_hex":"41"}'], 2,
                      "kind: expected a record kind code 0..255, got the number -3"),
    "bad_hex": (['{"t_ns":1,"kind":"rx","data_hex":"4g"}'], 2, "data_hex: not hex"),
    "odd_hex": (['{"t_ns":1,"kind":"rx","data_hex":"414"}'], 2, "data_hex: not hex"),
    "non_ascii_hex": (['{"t_ns":1,"kind":"rx","data_hex":"\u00e9\u00e9"}'], 2, "data_hex: not hex"),
    "hex_not_string": (['{"t_ns":1,"kind":"rx","data_hex":65}'], 2,
                       "data_hex: expected a string of hex digits, got the number 65"),
    "event_not_object": (['{"t_ns":1,"kind":"settings","event":[1]}'], 2,
                         "event: expected a JSON object, got an array"),
    "header_not_first": ([GOOD, HEADER], 3,
                         "header: must be the first line, before every record"),
    "second_header": ([HEADER], 2, "header: a second header line"),
}
BAD_HEADERS = {
    "header_not_object": ('{"header": [1]}', "header: expected a JSON object, got an array"),
    "header_field_type": ('{"header": {"host": 5}}', "header: SessionHeader member 'host' must be a str, not int"),
    "header_capture": ('{"header": {"capture": "radio"}}',
                       "header: capture must be 'client' or 'wire', not 'radio'"),
    "header_metadata": ('{"header": {"metadata": "x"}}',
                        "header: SessionHeader member 'metadata' must be a dict of str to str, not str"),
    # Found by jsonl_import_fuzz: the writer refused it after the importer
    # had let it through.
    "header_start_utc": ('{"header": {"start_utc": "20w6-11-23T10:00:00Z"}}',
                         'header.start_utc: the session header\'s start_utc "20w6-11-23T10:00:00Z"'),
    "header_start_utc_year": ('{"header": {"start_utc": "9999-01-01T00:00:00Z"}}',
                              "header.start_utc: the session header's start_utc"),
    # Members are SessionHeader's, checked by the bound type.
    "header_unknown_member": ('{"header": {"hots": "x"}}',
                              "header: the session header JSON has no member 'hots'"),
    "header_lone_surrogate": ('{"header": {"host": "\\ud800"}}',
                              "header: SessionHeader member 'host' is not valid UTF-8"),
    "header_metadata_surrogate": ('{"header": {"metadata": {"k": "\\udfff"}}}',
                                  "header: SessionHeader member 'metadata' is not valid UTF-8"),
}


def write_lines(path, lines):
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


@pytest.mark.parametrize("name", sorted(BAD_FILES))
def test_a_bad_line_is_a_clean_session_error_naming_line_and_field(tmp_path, capsys, name):
    lines, number, expected = BAD_FILES[name]
    src = write_lines(tmp_path / "in.jsonl", [HEADER, *lines])
    with pytest.raises(wiretape.SessionError) as raised:
        convert_module.convert(src, tmp_path / "out.wtape")
    message = str(raised.value)
    assert message.startswith(f"{src}:{number}: "), message
    assert expected in message
    assert "\n" not in message
    # The error's offset is where the bad line starts.
    assert raised.value.offset == len("\n".join([HEADER, *lines][:number - 1])) + 1
    # The CLI: one line, exit 1 (a damaged session file), no traceback.
    code, _, err = run_cli(capsys, "convert", str(src), str(tmp_path / "cli.wtape"),
                           "--from", "jsonl")
    assert code == cli.EXIT_CHECK_FAILED
    assert err.strip().splitlines() == [f"wiretape convert: error: {message}"]


@pytest.mark.parametrize("name", sorted(BAD_HEADERS))
def test_a_bad_header_is_a_clean_session_error(tmp_path, capsys, name):
    line, expected = BAD_HEADERS[name]
    src = write_lines(tmp_path / "in.jsonl", [line, GOOD])
    with pytest.raises(wiretape.SessionError, match=f"^{src}:1: ") as raised:
        convert_module.convert(src, tmp_path / "out.wtape")
    assert expected in str(raised.value)
    code, _, err = run_cli(capsys, "convert", str(src), str(tmp_path / "cli.jsonl.wtape"))
    assert code == cli.EXIT_CHECK_FAILED
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_not_utf8_is_a_clean_error(tmp_path, capsys):
    src = tmp_path / "in.jsonl"
    src.write_bytes(HEADER.encode() + b"\n" + b'{"t_ns":1,"kind":"rx","data_hex":"\xff"}\n')
    with pytest.raises(wiretape.SessionError, match=rf"^{src}:2: not UTF-8 text"):
        convert_module.convert(src, tmp_path / "out.wtape")


def test_records_before_the_bad_line_are_converted(tmp_path):
    src = write_lines(tmp_path / "in.jsonl", [HEADER, GOOD, GOOD, '{"t_ns":-1,"kind":"rx"}'])
    out = tmp_path / "out.wtape"
    with pytest.raises(wiretape.SessionError):
        convert_module.convert(src, out)
    assert [r.data for r in wiretape.SessionReader(str(out))] == [b"A", b"A"]


def test_valid_edges_convert(tmp_path):
    lines = [
        '{"t_ns":%d,"kind":"rx","data_hex":"41"}' % MAX_T_NS,
        '{"t_ns":0,"kind_code":200,"data_hex":"ff"}',  # a kind this version does not name
        '{"t_ns":1,"kind":"settings","event":{"baud":9600}}',
        '{"t_ns":2,"kind":"close"}',  # an event needs no payload
        "",
    ]
    src = write_lines(tmp_path / "in.jsonl", [HEADER, *lines])
    result = convert_module.convert(src, tmp_path / "out.wtape")
    assert result.records == 4
    # Readers skip the kind they do not name (docs/session-format.md).
    records = list(wiretape.SessionReader(str(tmp_path / "out.wtape")))
    assert [(r.t_ns, r.kind, r.data) for r in records] == [
        (MAX_T_NS, "rx", b"A"), (1, "settings", b'{"baud":9600}'), (2, "close", b"")]


def _load_fuzz_script():
    spec = importlib.util.spec_from_file_location("jsonl_import_fuzz",
                                                  ROOT / "fuzz" / "jsonl_import_fuzz.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("seed", sorted(p.name for p in CORPUS.iterdir()))
def test_the_fuzz_corpus_converts_or_fails_cleanly(tmp_path, seed):
    """What ctest's corpus replay is for the C++ fuzz targets."""
    fuzz = _load_fuzz_script()
    fuzz.check_input((CORPUS / seed).read_bytes(), str(tmp_path))


def test_the_reader_beside_the_writer_reads_back_what_it_wrote(tmp_path):
    """exports.jsonl.read_records reads the form write_records writes: the
    header first, then every record as (kind, t_ns, data, channel)."""
    from wiretape.exports import jsonl

    header = wiretape._core.SessionHeader(port_type="serial", capture="client")
    written = [wiretape._core.Record(5, "tx", b"AT\r"), wiretape._core.Record(9, "rx", b"OK")]
    path = tmp_path / "s.jsonl"
    jsonl.write_records(path, header.to_dict(), written)
    items = list(jsonl.read_records(str(path)))
    assert items[0][0] == "header" and items[0][1].port_type == "serial"
    assert [value for _, value in items[1:]] == [("tx", 5, b"AT\r", 0), ("rx", 9, b"OK", 0)]


def test_a_cassette_line_is_told_apart_from_a_record():
    from wiretape.exports import jsonl

    assert jsonl.looks_like_reserial({"test_x": {"rx": "", "tx": ""}})
    assert not jsonl.looks_like_reserial({"t_ns": 0, "kind": "rx", "data_hex": ""})


GOLDEN = ROOT / "tests" / "data" / "golden"
OLD_JSONL = ROOT / "tests" / "data" / "jsonl"


@pytest.mark.parametrize("name", ["v1_1", "v1_2_channels"])
def test_the_header_line_is_the_files_header_json(tmp_path, name):
    # One layout (DESIGN §25): the export's header is the session file's
    # header JSON, not the flat dict wiretape 0.1.0 wrote.
    out = tmp_path / "s.jsonl"
    convert_module.convert(GOLDEN / f"{name}.wtape", out)
    first = json.loads(out.read_text().splitlines()[0])
    header = wiretape.SessionReader(str(GOLDEN / f"{name}.wtape")).header
    assert first == {"header": json.loads(header.to_json())}


@pytest.mark.parametrize("old, original", [
    ("flat_header_provenance.jsonl", "v1_1.wtape"),
    ("flat_header_channels.jsonl", "v1_2_channels.wtape"),
])
def test_a_jsonl_file_with_the_old_flat_header_still_reads(tmp_path, old, original):
    from wiretape.exports import jsonl

    assert "version_major" in json.loads((OLD_JSONL / old).read_text().splitlines()[0])["header"]
    items = list(jsonl.read_records(str(OLD_JSONL / old)))
    source = wiretape.SessionReader(str(GOLDEN / original))
    assert items[0][0] == "header"
    assert items[0][1].to_dict() == source.header.to_dict()
    written_now = tmp_path / "now.jsonl"
    convert_module.convert(GOLDEN / original, written_now)
    records = [value for _, value in items[1:]]
    assert len(records) > 1
    assert records == [value for _, value in list(jsonl.read_records(str(written_now)))[1:]]
    converted = tmp_path / "back.wtape"
    convert_module.convert(OLD_JSONL / old, converted)
    assert wiretape.SessionReader(str(converted)).header.to_dict() == source.header.to_dict()
