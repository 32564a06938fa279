from foldfab.cli import run

raise SystemExit(run())
