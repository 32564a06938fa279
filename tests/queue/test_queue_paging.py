"""A big queue: ``queue list`` a page at a time (keyset paging on the job id), and the indexes that
keep listing and claiming from reading the whole queue, on both stores."""

from __future__ import annotations

import json
import re
from contextlib import contextmanager
from pathlib import Path

import pytest

from foldfab.devices import load_device
from foldfab.programs.program import Program
from foldfab.queue.records import NewJob, WorkerId
from foldfab.queue.snapshot import make_snapshot
from helpers.cli import run as run_cli
from helpers.queues import fill_jobs


def snapshot():
    device = load_device("hp7475a")
    return make_snapshot(Path("job.toml"), "[design]\n", "paged", device,
                         Program("IN;SP1;PU0,0;PD400,400;SP0;", "hpgl", device.name, (), ()))


def pages(store, state, limit) -> list[int]:
    """Every id, page by page (each page starts after the last id of the one before)."""
    ids, after = [], 0
    for _ in range(1000):
        page = store.page(state, after, limit)
        assert len(page.jobs) <= limit
        ids.extend(job.id for job in page.jobs)
        if not page.more:
            return ids
        assert len(page.jobs) == limit
        after = page.jobs[-1].id
        assert page.more == len([j for j in store.jobs(state) if j.id > after])
    raise AssertionError("paging did not end")


def test_pages_hold_every_job_exactly_once_while_the_queue_changes(store):
    worker = WorkerId.current()
    ids = store.add([NewJob(snapshot(), f"sim://p{i}", i % 3, 9) for i in range(7)])
    for _ in range(5):  # a few done, one running, some cancelled
        claim = store.claim(worker, 60)
        store.finish(claim.job.id, worker, "done", "drawn")
    store.claim(worker, 60)
    for job_id in ids[40:50]:
        store.cancel(job_id)
    for state in (None, "queued", "done", "cancelled", "running", "failed"):
        expected = [job.id for job in store.jobs(state)]
        for limit in (1, 4, 10, 63, 500):
            assert pages(store, state, limit) == expected, (state, limit)
    # a job added or removed while an operator pages: each job on one page, new ones at the end
    first = store.page(None, 0, 20)
    store.remove(ids[5])
    (new,) = store.add([NewJob(snapshot(), "sim://new")])
    rest, after = [], first.jobs[-1].id
    while True:
        page = store.page(None, after, 20)
        rest.extend(job.id for job in page.jobs)
        if not page.more:
            break
        after = page.jobs[-1].id
    seen = [job.id for job in first.jobs] + rest
    assert len(seen) == len(set(seen)) and seen[-1] == new
    assert set(seen) == set(ids) | {new}  # the removed job was listed before it went
    assert store.page(None, new, 5).jobs == [] and store.page(None, new, 5).more == 0
    assert store.page(None, 2 ** 70, 5).jobs == [] and store.page(None, -5, 1).jobs[0].id == seen[0]
    with pytest.raises(ValueError):
        store.page(None, 0, 0)


def test_queue_list_shows_a_page_and_the_command_for_the_next(store, capsys):
    store.add([NewJob(snapshot(), "sim://p", 0, 130)])
    queue = ["--queue", store.location]
    code, out, _ = run_cli(capsys, "queue", "list", *queue)
    lines = out.splitlines()
    assert code == 0 and len(lines) == 1 + 100 + 1
    assert [int(line.split()[0]) for line in lines[1:-1]] == list(range(1, 101))
    assert lines[-1] == "... 30 more jobs: foldfab queue list --after 100 (--limit 0 lists all)"
    command = re.match(r"\.\.\. \d+ more jobs: foldfab (.*) \(", lines[-1]).group(1).split()
    code, out, _ = run_cli(capsys, *command, *queue)
    assert [int(line.split()[0]) for line in out.splitlines()[1:]] == list(range(101, 131))
    assert len(json.loads(run_cli(capsys, "queue", "list", "--json", *queue)[1])) == 130  # JSON: all
    assert len(json.loads(run_cli(capsys, "queue", "list", "--json", "--limit", "7", *queue)[1])) == 7
    assert len(run_cli(capsys, "queue", "list", "--limit", "0", *queue)[1].splitlines()) == 131
    out = run_cli(capsys, "queue", "list", "--state", "queued", "--limit", "20", "--after", "100", *queue)[1]
    assert out.splitlines()[-1] == ("... 10 more queued jobs: foldfab queue list --after 120 --state queued "
                                    "--limit 20 (--limit 0 lists all)")
    out = run_cli(capsys, "queue", "list", "--after", "130", *queue)[1]
    assert out == f"no jobs after job 130 in {store.location}\n"
    for args, message in ((["--limit", "-1"], "argument --limit: expected a number of jobs from 0 to "),
                          (["--limit", str(2 ** 64)], f"argument --limit: expected a number of jobs from 0 to "
                                                      f"{2 ** 63 - 1}, got {2 ** 64}"),
                          (["--after", str(2 ** 64)], "argument --after: expected a job id from 0 to "),
                          (["--after", "x"], "argument --after: expected a whole number, got 'x'")):
        with pytest.raises(SystemExit) as exit:
            run_cli(capsys, "queue", "list", *args, *queue)
        assert exit.value.code == 2 and message in capsys.readouterr().err


@contextmanager
def recorded(store):
    """The statements the store runs meanwhile, with their parameters."""
    statements = []

    class Recorder:
        def __init__(self, db):
            self.db = db

        def execute(self, sql, params=()):
            statements.append((sql, params))
            return self.db.execute(sql, params)

        def __getattr__(self, name):
            return getattr(self.db, name)

    def wrap(method):
        @contextmanager
        def transaction(*args, **kwargs):
            with method(*args, **kwargs) as db:
                yield Recorder(db)
        return transaction

    store._read, store._write = wrap(store._read), wrap(store._write)
    try:
        yield statements
    finally:
        del store._read, store._write


def plan(store, statements, marker: str) -> str:
    """The query plan of the first statement that contains ``marker``."""
    sql, params = next((sql, params) for sql, params in statements if marker in sql)
    explain = "EXPLAIN" if hasattr(store, "url") else "EXPLAIN QUERY PLAN"
    with store._read() as db:
        return "\n".join(str(row[-1]) for row in db.execute(f"{explain} {sql}", params).fetchall())


def test_a_page_and_a_claim_walk_their_indexes_instead_of_sorting_the_queue(store):
    """20,000 jobs: a page of the listing reads the primary key in order; a claim walks the
    claim-order index over the runnable jobs to the first free plotter."""
    fill_jobs(store, snapshot(), 20_000)
    with recorded(store) as statements:
        assert len(store.page(None, 0, 100).jobs) == 100
        assert store.claim(WorkerId.current(), 60) is not None
    listing = plan(store, statements, "ORDER BY j.id")
    claim = plan(store, statements, store.queries.claim_order)
    if hasattr(store, "url"):  # PostgreSQL
        assert "Index Scan using jobs_pkey on jobs j" in listing and "Sort" not in listing, listing
        assert "Index Scan using jobs_by_claim_order on jobs j" in claim and "Sort" not in claim, claim
    else:
        assert "SEARCH j USING INTEGER PRIMARY KEY (rowid>?)" in listing and "TEMP B-TREE" not in listing, listing
        assert "SCAN j USING INDEX jobs_by_claim_order" in claim and "TEMP B-TREE" not in claim, claim
