"""Atomic output: a set of files is written whole or not at all, links are written
through, devices and FIFOs are written in place."""

from __future__ import annotations

import os
import stat
import threading

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from foldfab.atomic import stream_files, write_files, write_text


def contents(folder):
    return {p.name: (p.read_bytes() if p.is_file() else "dir") for p in sorted(folder.iterdir())}


@settings(max_examples=60, deadline=None)
@given(existing=st.lists(st.booleans(), min_size=1, max_size=5), bad=st.integers(0, 4), data=st.data())
def test_a_failing_set_leaves_every_target_as_it_was(tmp_path_factory, existing, bad, data):
    folder = tmp_path_factory.mktemp("set")
    paths = [folder / f"out{i}.txt" for i in range(len(existing))]
    for path, there in zip(paths, existing):
        if there:
            path.write_bytes(b"old " + path.name.encode())
    bad = bad % len(paths)
    paths[bad].unlink(missing_ok=True)
    paths[bad].mkdir()  # cannot be replaced by a file
    before = contents(folder)
    files = [(path, data.draw(st.binary(max_size=64))) for path in paths]
    with pytest.raises(IsADirectoryError) as caught:
        write_files(files)
    assert caught.value.filename == str(paths[bad])
    assert contents(folder) == before  # nothing replaced, no temporary file left


def test_a_set_is_written_whole(tmp_path):
    (tmp_path / "a.txt").write_text("old")
    write_files([(tmp_path / "a.txt", b"new a"), (tmp_path / "b.txt", b"new b")])
    assert contents(tmp_path) == {"a.txt": b"new a", "b.txt": b"new b"}


def test_a_symbolic_link_is_written_through(tmp_path):
    (tmp_path / "real").mkdir()
    target = tmp_path / "real" / "t.txt"
    target.write_text("old")
    (tmp_path / "link.txt").symlink_to(target)
    (tmp_path / "dangling.txt").symlink_to(tmp_path / "real" / "new.txt")
    write_text(tmp_path / "link.txt", "through")
    write_text(tmp_path / "dangling.txt", "created")
    assert (tmp_path / "link.txt").is_symlink() and target.read_text() == "through"
    assert (tmp_path / "dangling.txt").is_symlink() and (tmp_path / "real" / "new.txt").read_text() == "created"
    assert sorted(p.name for p in (tmp_path / "real").iterdir()) == ["new.txt", "t.txt"]


def reading_fifo(path):
    """A FIFO at ``path`` and a thread reading it whole: (the thread, the list it appends to)."""
    os.mkfifo(path)
    received = []
    reader = threading.Thread(target=lambda: received.append(path.read_bytes()))
    reader.start()
    return reader, received


def test_a_fifo_is_written_in_place(tmp_path):
    fifo = tmp_path / "pipe"
    reader, received = reading_fifo(fifo)
    write_text(fifo, "through the pipe\n")
    reader.join(10)
    assert received == [b"through the pipe\n"]
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)  # still a FIFO, not replaced by a file


def test_a_device_is_written_in_place_and_its_error_names_it():
    write_text("/dev/null", "discarded")
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
    with pytest.raises(OSError) as caught:
        write_text("/dev/full", "no room")
    assert caught.value.filename == "/dev/full"
    assert stat.S_ISCHR(os.stat("/dev/full").st_mode)


@settings(max_examples=40, deadline=None)
@given(pieces=st.lists(st.lists(st.binary(max_size=300), max_size=8), min_size=1, max_size=3))
def test_streamed_files_hold_their_pieces_joined(tmp_path_factory, pieces):
    folder = tmp_path_factory.mktemp("stream")
    paths = [folder / f"out{i}.bin" for i in range(len(pieces))]
    with stream_files(paths) as files:
        for file, chunks in zip(files, pieces):
            for chunk in chunks:
                file.write(chunk)
            assert file.read() == b"".join(chunks)   # what it holds so far, read back
        assert not any(path.exists() for path in paths)   # nothing in place before the end
    assert contents(folder) == {path.name: b"".join(chunks) for path, chunks in zip(paths, pieces)}


@pytest.mark.parametrize("error", [RuntimeError, KeyboardInterrupt, OSError])
def test_a_stream_stopped_midway_leaves_every_target_as_it_was(tmp_path, error):
    (tmp_path / "a.txt").write_bytes(b"old a")
    with pytest.raises(error) as caught:
        with stream_files([tmp_path / "a.txt", tmp_path / "b.txt"]) as (a, b):
            a.write(b"new a, half")
            b.write(b"new b, half")
            raise error("stopped")
    assert caught.value.args == ("stopped",)   # the caller's own error, as it was
    assert contents(tmp_path) == {"a.txt": b"old a"}   # no temporary file either


def test_a_stream_into_a_fifo_is_written_in_place_at_the_end(tmp_path):
    fifo = tmp_path / "pipe"
    reader, received = reading_fifo(fifo)
    with stream_files([fifo]) as [pipe]:
        pipe.write(b"through ")
        pipe.write(b"the pipe\n")
        assert pipe.read() == b"through the pipe\n"
    reader.join(10)
    assert received == [b"through the pipe\n"]


def test_a_failing_stream_write_names_its_file(tmp_path, monkeypatch):
    with pytest.raises(OSError) as caught:
        with stream_files([tmp_path / "a.txt"]) as [file]:
            monkeypatch.setattr(file.handle, "write", lambda data: (_ for _ in ()).throw(OSError(28, "No space")))
            file.write(b"data")
    assert caught.value.filename == str(tmp_path / "a.txt") and caught.value.errno == 28
    assert contents(tmp_path) == {}
