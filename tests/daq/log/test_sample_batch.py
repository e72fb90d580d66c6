"""``/daq/samples`` read together (``decode_written_samples``): a message in the writer's
own form gives exactly what ``decode_sample`` gives it; any other (nulls, another
recorder's spacing, damage, a payload crafted to fool a batch parse) is left to
``decode_sample``, so ``read_run`` reports the same first bad message as when each
message was decoded as it came."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from foxglove_schemas_protobuf.Log_pb2 import Log
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap.writer import CompressionType, Writer
from mcap_protobuf.schema import build_file_descriptor_set

from daq.log import LogError, read_run
from daq.log.format import (
    MAX_ABS_STRAIN,
    BadMessageError,
    decode_sample,
    decode_written_samples,
    encode_samples,
)

PERIOD_NS = 2_500_000
UTC_ZERO_NS = 1_795_558_576_943_462_090


def _written(n: int, *, seed: int = 1, utc: bool = True, first: int = 0) -> list[bytes]:
    """n samples as the writer writes them (``encode_samples``), some values awkward to
    print: negative zero, subnormals, values at the bounds, a null."""
    rng = np.random.default_rng(seed)
    t = (first + np.arange(n)) * PERIOD_NS
    angle = rng.normal(size=n)
    strain = rng.normal(size=(n, 4)) * 1e-4
    volts = rng.normal(size=(n, 5))
    if n > 6:
        angle[1] = -0.0
        strain[2, 1] = 5e-324
        strain[3, 0] = -MAX_ABS_STRAIN
        volts[4, 4] = 1e-300
        volts[5, 2] = 123.0
        angle[6] = np.nan  # written as null: decode_sample's to read
    return encode_samples(t, angle, strain, volts, UTC_ZERO_NS if utc else None)


def _same_as_decode_sample(data: list[bytes]) -> int:
    """Check decode_written_samples against decode_sample message by message; the number
    of messages it read itself."""
    t_ns, values, ok = decode_written_samples(data)
    assert t_ns.shape == ok.shape == (len(data),) and values.shape == (len(data), 10)
    for i, d in enumerate(data):
        try:
            want_t, want = decode_sample(d)
        except BadMessageError:
            assert not ok[i], d
            continue
        if ok[i]:
            assert t_ns[i] == want_t, d
            # bit for bit (-0.0 stays negative)
            assert values[i].tobytes() == np.asarray(want, np.float64).tobytes(), d
    return int(ok.sum())


def test_the_writers_samples_are_read_together_exactly() -> None:
    for utc in (True, False):
        data = _written(400, utc=utc)
        assert _same_as_decode_sample(data) == 399  # all but the null
    # before the per-gauge fields and the header, the writer wrote neither
    old = [json.dumps(json.loads(d), separators=(",", ":")).encode() for d in _written(20)]
    old = [re.sub(rb',"strain_g1".*\}$', b"}", d) for d in old]
    assert b"strain_g" not in old[0] and b"header" not in old[0]
    assert _same_as_decode_sample(old) == 19


def _swap(data: bytes, old: bytes, new: bytes) -> bytes:
    assert old in data
    return data.replace(old, new, 1)


def test_anything_but_the_writers_form_is_left_to_decode_sample() -> None:
    d = _written(8)[0]
    tail = d[d.index(b',"header"') :]
    cases = [
        d + b" ",  # trailing whitespace: json's, not the writer's
        b" " + d,
        d.replace(b",", b", "),  # another recorder's spacing
        d + b"," + d,  # two samples in one payload
        d[:-1],
        d[: len(d) // 2],
        d + b"\n" + d,
        _swap(d, b'"sec":0', b'"sec":-0'),
        _swap(d, b'"sec":0', b'"sec":00'),
        _swap(d, b'"sec":0', b'"sec":0.0'),
        _swap(d, b'"sec":0', b'"sec":1000000000000000000'),  # 19 digits
        _swap(d, b'"sec":0', b'"sec":9223372036'),  # beyond 2**63 ns
        _swap(d, b'"sec":0', b'"sec":9223372035'),  # the last second that fits
        _swap(d, b'"nsec":0', b'"nsec":1000000000'),
        _swap(d, b'"nsec":0', b'"nsec":999999999'),
        _swap(d, b'"rocker_angle_rad":', b'"rocker_angle_rad":1e999,"x":'),
        _swap(d, b'"rocker_angle_rad":', b'"rocker_angle_rad":-1e999,"x":'),
        _swap(d, b'"rocker_angle_rad":', b'"rocker_angle_rad":3,"x":'),
        _swap(d, b'"rocker_angle_rad":', b'"rocker_angle_rad":NaN,"x":'),
        _swap(d, b'"rocker_angle_rad":', b'"rocker_angle_rad":null,"x":'),
        _swap(d, b'"rocker_angle_rad":', b'"rocker_angle_rad":true,"x":'),
        _swap(d, b'"rocker_angle_rad":', b'"rocker_angle_rad":"1.5","x":'),
        _swap(d, b'"rocker_angle_rad":', b'"rocker_angle_rad":1000.5,"x":'),
        _swap(d, b'"rocker_angle_rad":', b'"rocker_angle_rad":1000.0,"rocker_angle_rad":'),
        _swap(d, b'"raw_volts":[', b'"raw_volts":[1.0,'),
        _swap(d, b'"raw_volts":[', b'"raw_volts":[1.e5,'),
        _swap(d, b'"raw_volts":[', b'"raw_volts":[.5,'),
        _swap(d, b'"raw_volts":[', b'"raw_volts":[+0.5,'),
        _swap(d, b'"raw_volts":[', b'"raw_volts":[0.5E+07,'),  # valid JSON: out of bounds
        _swap(d, b'"raw_volts":[', b'"raw_volts":[0.5E-07,'),  # valid and within
        _swap(d, b'"raw_volts":[', b'"raw_volts":[05.5,'),
        _swap(d, b'"strain":[', b'"strain":[1.5,'),
        _swap(d, b'"strain_g1":', b'"strain_g1":"'),
        _swap(d, b'"strain_g2":', b'"strain_g2":0.5,"strain_g2":'),
        _swap(d, b'"frame_id":"daq"', b'"frame_id":"cam"'),
        _swap(d, b'"frame_id":"daq"', b'"frame_id":"daq\\u0000"'),
        _swap(d, b'"stamp":{"sec":', b'"stamp":{"sec":-'),
        _swap(d, b'"stamp":{"sec":', b'"stamp":{"sec":1' + b"0" * 5000),  # too long for int
        _VOLT0.sub(b'"raw_volts":[0.5E-07,', d),  # the writer's form: read together
        _VOLT0.sub(b'"raw_volts":[5e-3,', d),  # the same
        _VOLT0.sub(b'"raw_volts":[-0.0,', d),  # the same
        _VOLT0.sub(b'"raw_volts":[0.5E+07,', d),  # out of bounds
        _VOLT0.sub(b'"raw_volts":[5,', d),  # an int
        _VOLT0.sub(b'"raw_volts":[5.,', d),
        _VOLT0.sub(b'"raw_volts":[5e,', d),
        _VOLT0.sub(b'"raw_volts":[-,', d),
        _VOLT0.sub(b'"raw_volts":[Infinity,', d),
        d.replace(tail, b"}"),  # no header: the writer's too
        d.replace(tail, b',"header":{}}'),
        d.replace(b"{", b"\xef\xbb\xbf{", 1),  # a BOM
        d.replace(b"{", b"\x00{", 1),
        d.decode().encode("utf-16-le"),
        b"",
        b"{}",
        b"[" + d + b"]",
    ]
    _same_as_decode_sample(cases)
    together = [cases[i] for i in np.flatnonzero(decode_written_samples(cases)[2])]
    assert together == [
        cases[12],  # the last second that fits
        cases[14],  # nsec 999999999
        cases[36],  # a negative UTC second (not read)
        cases[38],  # 0.5E-07
        cases[39],
        cases[40],
        cases[47],  # no header
    ]
    assert _same_as_decode_sample([]) == 0


def test_every_single_byte_edit_is_read_as_decode_sample_reads_it() -> None:
    """Each byte of a written sample (with and without the header) dropped, doubled or
    replaced by a byte that matters to JSON."""
    for d in (_written(8)[3], _written(8, utc=False)[3]):
        edits = []
        for i in range(len(d)):
            edits += [d[:i] + d[i + 1 :], d[:i] + d[i : i + 1] + d[i:]]
            edits += [d[:i] + bytes([b]) + d[i + 1 :] for b in b'0.e-,:"}] ' if b != d[i]]
        assert _same_as_decode_sample(edits) > 0


_VOLT0 = re.compile(rb'"raw_volts":\[[^,]+,')
_EDIT_BYTES = b'0123456789.eE+-,:{}[]" \\nultrfas\n\x00\xff'


@settings(max_examples=300, deadline=None)
@given(
    st.integers(0, 7),
    st.lists(
        st.tuples(st.integers(0, 10_000), st.sampled_from(["put", "drop", "add"]), st.integers()),
        max_size=3,
    ),
)
def test_damaged_payloads_are_read_as_decode_sample_reads_them(
    which: int, edits: list[tuple[int, str, int]]
) -> None:
    """Any edit of a written sample: read together exactly as decode_sample reads it, or
    left to it."""
    data = bytearray(_written(8, seed=which)[which])
    for at, kind, byte in edits:
        at %= len(data) + 1
        b = _EDIT_BYTES[byte % len(_EDIT_BYTES)]
        if kind == "put" and at < len(data):
            data[at] = b
        elif kind == "drop" and at < len(data):
            del data[at]
        elif kind == "add":
            data.insert(at, b)
    _same_as_decode_sample([bytes(data)])


def _log(
    path: Path,
    samples: list[bytes],
    *,
    times: list[int] | None = None,
    events: dict[int, bytes] | None = None,
    chunked: bool = True,
) -> None:
    """A log holding ``samples`` (sample k at log time k * PERIOD_NS unless ``times``
    says), with ``events[k]`` written right after sample k, in one chunk (``chunked``)
    or as messages of their own, read as a stream."""
    times = [k * PERIOD_NS for k in range(len(samples))] if times is None else times
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=1 << 22, compression=CompressionType.ZSTD, use_chunking=chunked)
        w.start(profile="beambench", library="test")
        sid = w.register_schema("beambench.DaqSample", "jsonschema", b'{"type":"object"}')
        samples_id = w.register_channel("/daq/samples", "json", sid)
        fds = build_file_descriptor_set(Log).SerializeToString()
        lid = w.register_schema(Log.DESCRIPTOR.full_name, "protobuf", fds)
        events_id = w.register_channel("/events", "protobuf", lid)
        w.add_metadata("run", {"run_id": "batch"})
        for k, (t, data) in enumerate(zip(times, samples, strict=True)):
            w.add_message(samples_id, t, data, t, k)
            if events and k in events:
                w.add_message(events_id, t, events[k], t, k)
        w.finish()


def _event(t_ns: int, name: str) -> bytes:
    msg = Log(level=Log.INFO, message="", name=name)
    msg.timestamp.seconds, msg.timestamp.nanos = divmod(t_ns, 1_000_000_000)
    return msg.SerializeToString()


def _error(path: Path) -> str:
    with pytest.raises(LogError) as err:
        read_run(path)
    return str(err.value)


def _sample_error(path: Path, k: int, data: bytes) -> str:
    """read_run's error for a bad sample k, from decode_sample itself."""
    with pytest.raises(BadMessageError) as err:
        decode_sample(data)
    return (
        f"{path}: bad /daq/samples message (sequence {k}, log time {k * PERIOD_NS} ns): {err.value}"
    )


def test_read_run_gives_each_sample_what_decode_sample_gives_it(tmp_path: Path) -> None:
    data = _written(300)
    data[7] = json.dumps({**json.loads(data[7]), "raw_volts": [3, 1.5, 0, -2, 1e-3]}).encode()
    data[8] = data[8].replace(b",", b", ")  # another recorder's spacing
    path = tmp_path / "run.mcap"
    _log(path, data)
    run = read_run(path)
    want = np.array([decode_sample(d)[1] for d in data])
    got = np.column_stack([run.samples.rocker_angle_rad, run.samples.strain, run.samples.raw_volts])
    assert got.tobytes() == want.tobytes()
    assert np.isnan(run.samples.rocker_angle_rad[6]) and np.signbit(got[1, 0])
    assert list(run.samples.t_ns) == [k * PERIOD_NS for k in range(300)]


def test_a_payload_holding_two_samples_is_refused(tmp_path: Path) -> None:
    """Joined with commas into one JSON array, ``{s},{s}`` would read as two samples."""
    data = _written(50)
    data[20] = data[20] + b"," + data[21]
    path = tmp_path / "run.mcap"
    _log(path, data)
    msg = _error(path)
    assert msg == _sample_error(path, 20, data[20])
    assert "not JSON (Extra data at byte" in msg


def test_payloads_valid_only_when_joined_are_refused_at_the_first(tmp_path: Path) -> None:
    """Sample 10 opens a string that sample 11 closes (``"x":"`` + ``,`` + ``"}`` would
    join into one object) while sample 30 holds two samples: a batch parse of the
    messages joined with commas would count the right number of objects. Sample 10 is
    the first bad message."""
    data = _written(50)
    data[10] = data[10][:-1] + b',"x":"'
    data[11] = b'"}'
    data[30] = data[30] + b"," + data[31]
    path = tmp_path / "run.mcap"
    _log(path, data)
    joined = json.loads(b"[" + b",".join(data) + b"]")
    assert len(joined) == len(data)  # what a batch parse would have accepted
    msg = _error(path)
    assert msg == _sample_error(path, 10, data[10])
    assert "Unterminated string" in msg
    data[10], data[11] = _written(12)[10:12]
    path.unlink()
    _log(path, data)
    assert _error(path) == _sample_error(path, 30, data[30])


def _one(k: int, t_ns: int, values: list[float]) -> bytes:
    """Sample k as the writer writes it, at ``t_ns``, holding ``values``."""
    v = np.asarray(values, np.float64)[None, :]
    return encode_samples(np.array([t_ns]), v[:, 0], v[:, 1:5], v[:, 5:], UTC_ZERO_NS)[0]


_FINE = [0.5, 1e-4, 2e-4, 3e-4, 4e-4, 1.5, 0.1, 0.2, 0.3, 0.4]
_NSEC = re.compile(rb'"nsec":[0-9]+')


@pytest.mark.parametrize(
    ("bad", "problem"),
    [
        (_one(33, 9_223_372_036 * 10**9, _FINE), "timestamp.sec = 9223372036 is outside"),
        (_NSEC.sub(b'"nsec":1000000000', _one(33, 0, _FINE), 1), "timestamp.nsec = 1000000000"),
        (_one(33, 33 * PERIOD_NS, [1000.5, *_FINE[1:]]), "rocker_angle_rad = 1000.5 is outside"),
        (_one(33, 33 * PERIOD_NS, [*_FINE[:5], -1000.5, *_FINE[6:]]), "raw_volts[0] = -1000.5"),
        (_one(33, 33 * PERIOD_NS, [_FINE[0], 1.5, *_FINE[2:]]), "strain[0] = 1.5 is outside"),
        (
            re.sub(rb'"rocker_angle_rad":[^,]+', b'"rocker_angle_rad":1e999', _one(33, 0, _FINE)),
            "rocker_angle_rad = inf is outside",
        ),
    ],
)
def test_a_sample_in_the_writers_form_out_of_range_is_refused(
    tmp_path: Path, bad: bytes, problem: str
) -> None:
    assert decode_written_samples([bad])[2].tolist() == [False]
    data = _written(40)
    data[33] = bad
    path = tmp_path / "run.mcap"
    _log(path, data)
    msg = _error(path)
    assert msg == _sample_error(path, 33, bad)
    assert problem in msg


def test_a_sample_whose_time_is_not_its_log_time_is_refused(tmp_path: Path) -> None:
    data = _written(40)
    times = [k * PERIOD_NS for k in range(40)]
    times[25] += 1
    path = tmp_path / "run.mcap"
    _log(path, data, times=times)
    assert _error(path) == (
        f"{path}: bad /daq/samples message (sequence 25, log time {times[25]} ns): its "
        f"timestamp {25 * PERIOD_NS} ns is not its log time"
    )


@pytest.mark.parametrize("chunked", [True, False])
def test_the_first_bad_message_in_the_file_is_named_whatever_its_topic(
    tmp_path: Path, chunked: bool
) -> None:
    data = _written(60)
    bad_sample = data[40][:-3]
    data[40] = bad_sample
    bad_event = _event(0, "")  # an event needs a name
    path = tmp_path / "run.mcap"
    # the event first, then the sample
    _log(path, data, events={5: _event(5, "start"), 20: bad_event}, chunked=chunked)
    assert _error(path) == (
        f"{path}: bad /events message (sequence 20, log time {20 * PERIOD_NS} ns): an event "
        "needs a name"
    )
    # the sample first, then the event
    path.unlink()
    _log(path, data, events={50: bad_event}, chunked=chunked)
    assert _error(path) == _sample_error(path, 40, bad_sample)
