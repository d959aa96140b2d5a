"""``dms record info`` and ``dms record play`` on hostile and odd files, each the real
command in a subprocess.

A file of a few kilobytes whose zstd chunk inflates to hundreds of megabytes (a chunk
bomb) is refused in one line under an address-space limit well below what reading it
whole takes; so is a chunk that claims a small size and inflates past the bound, and a
message over its own bound. A recording whose stored configuration lacks a field is
read, with a warning naming the field. No network: the player's Zenoh session listens
nowhere and connects to nothing.
"""

from __future__ import annotations

import json
import resource
import struct
import subprocess
import sys
from pathlib import Path

import pytest
import zstandard
from mcap.data_stream import RecordBuilder
from mcap.records import Channel, Chunk, DataEnd, Footer, Header
from mcap.writer import CompressionType, Writer

from sim.mcap_read import MAX_CHUNK_BYTES, MAX_MESSAGE_BYTES, MIB
from sim.recording import McapRecorder, read_recording

pytestmark = pytest.mark.integration

MAGIC = b"\x89MCAP0\r\n"
T0 = 1_700_000_000_000_000_000
ADDRESS_SPACE = 400 * MIB
"""The child's address-space limit: about twice what `dms record play` needs to start,
and under half of what inflating a 300 MB message whole takes (one copy in zstd's
output, one in the chunk's stream, one in the message)."""


def chunk_bomb(size: int, declared: int | None = None) -> bytes:
    """An MCAP file with one zstd chunk holding one message of ``size`` zero bytes on
    ``robots/mini/dms/state``, compressed in steps (the test never holds it whole);
    ``declared``: the inflated size the chunk claims (default: the true one)."""
    header = struct.pack("<BQHIQQ", 5, 22 + size, 1, 0, T0, T0)  # a Message record's header
    compressor = zstandard.ZstdCompressor().compressobj()
    parts = [compressor.compress(header)]
    block = bytes(MIB)
    for _ in range(size // MIB):
        parts.append(compressor.compress(block))
    parts.append(compressor.flush())
    out = RecordBuilder()
    out.write(MAGIC)
    Header(profile="", library="test").write(out)
    Channel(
        id=1, topic="robots/mini/dms/state", message_encoding="json", schema_id=0, metadata={}
    ).write(out)
    Chunk(
        message_start_time=T0,
        message_end_time=T0,
        uncompressed_size=declared if declared is not None else len(header) + size,
        uncompressed_crc=0,
        compression="zstd",
        data=b"".join(parts),
    ).write(out)
    DataEnd(data_section_crc=0).write(out)
    Footer(summary_start=0, summary_offset_start=0, summary_crc=0).write(out)
    out.write(MAGIC)
    return bytes(out.end())  # type: ignore[no-untyped-call]


def isolated_zenoh(tmp_path: Path) -> Path:
    path = tmp_path / "alone.json5"
    path.write_text(
        json.dumps(
            {
                "mode": "peer",
                "connect": {"endpoints": []},
                "listen": {"endpoints": []},
                "scouting": {"multicast": {"enabled": False}},
            }
        )
    )
    return path


def limited(*args: str) -> subprocess.CompletedProcess[str]:
    """``dms ARGS...`` under :data:`ADDRESS_SPACE`."""

    def cap() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))

    return subprocess.run(
        [sys.executable, "-m", "dms.cli", *args],
        capture_output=True,
        text=True,
        timeout=120,
        preexec_fn=cap,
    )


def refused_in_one_line(done: subprocess.CompletedProcess[str], *fragments: str) -> None:
    lines = done.stderr.strip().splitlines()
    assert done.returncode != 0, done.stderr
    assert len(lines) == 1 and lines[0].startswith("dms: "), done.stderr
    assert "MemoryError" not in done.stderr and "Traceback" not in done.stderr
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])


def small_recording(path: Path) -> Path:
    recorder = McapRecorder(path, "mini")
    for tick in range(3):
        payload = json.dumps({"tick": tick}).encode()
        recorder.write("robots/mini/dms/state", payload, T0 + tick * 1_000_000)
    recorder.close()
    return path


@pytest.mark.parametrize("declared", ["honest", "lying"])
def test_a_chunk_bomb_is_refused_in_one_line_within_a_memory_limit(
    tmp_path: Path, declared: str
) -> None:
    bomb = tmp_path / "bomb.mcap"
    bomb.write_bytes(chunk_bomb(300 * MIB, None if declared == "honest" else 1000))
    assert bomb.stat().st_size < 16 * 1024
    limit = f"{MAX_CHUNK_BYTES // MIB:.1f} MiB"
    alone = str(isolated_zenoh(tmp_path))
    for args in (("info", str(bomb)), ("play", str(bomb), "--zenoh-config", alone)):
        done = limited("record", *args)
        refused_in_one_line(done, str(bomb), "a chunk of", limit, "mcap compress --chunk-size")
    # the limit leaves room for the commands themselves: a recording of dms record passes
    small = small_recording(tmp_path / "small.mcap")
    done = limited("record", "info", str(small))
    assert done.returncode == 0 and "Messages:      3" in done.stdout, done.stderr
    done = limited("record", "play", str(small), "--zenoh-config", alone, "--rate", "100")
    assert done.returncode == 0 and "3 messages played" in done.stderr, done.stderr


def test_a_message_over_its_bound_is_refused_in_one_line(tmp_path: Path) -> None:
    size = MAX_MESSAGE_BYTES + MIB  # a chunk under its own bound
    large = tmp_path / "large.mcap"
    large.write_bytes(chunk_bomb(size))
    done = limited("record", "info", str(large))
    refused_in_one_line(done, "a message of 17.0 MiB", f"{MAX_MESSAGE_BYTES // MIB:.1f} MiB")


def test_a_stored_configuration_without_settings_is_read_with_a_warning(tmp_path: Path) -> None:
    path = tmp_path / "old.mcap"
    with path.open("wb") as stream:
        writer = Writer(stream, compression=CompressionType.ZSTD)
        writer.start(profile="", library="another version")
        channel = writer.register_channel("robots/mini/dms/state", "json", 0)
        for tick in range(2):
            data = json.dumps({"tick": tick}).encode()
            writer.add_message(channel, T0 + tick, data, T0 + tick)
        # written by a recorder that did not store the settings; the seed is fine
        writer.add_metadata(
            "dms-config", {"robot_id": "mini", "seed": "7", "versions": "{}", "files": "[]"}
        )
        writer.finish()  # type: ignore[no-untyped-call]
    config = read_recording(path).config
    assert config is not None and config.missing == ("settings",) and config.seed == 7
    assert config.settings == {}

    info = limited("record", "info", str(path))
    assert info.returncode == 0, info.stderr
    assert "lacks 'settings'" in info.stderr and "Seed:          7" in info.stdout, info
    assert len(info.stderr.strip().splitlines()) == 1, info.stderr
    described = json.loads(limited("record", "info", str(path), "--json").stdout)
    assert described["config"]["seed"] == 7 and described["complete"] is True
    alone = str(isolated_zenoh(tmp_path))
    played = limited("record", "play", str(path), "--zenoh-config", alone, "--rate", "100")
    assert played.returncode == 0, played.stderr
    assert "lacks 'settings'" in played.stderr and "2 messages played" in played.stderr
