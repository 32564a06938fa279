"""Atomic output: a set of files is written whole or not at all, links are written
through, devices and FIFOs are written in place."""

from __future__ import annotations

import os
import stat
import threading

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from foldfab.atomic import write_files, write_text


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


def test_a_fifo_is_written_in_place(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    received = []
    reader = threading.Thread(target=lambda: received.append(fifo.read_bytes()))
    reader.start()
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
