"""What the scene drivers in tools/ share (tools/README.md): one runner (runner.py), one log
reader (logs.py), one settled-state cache (cache.py), grains on disk and their contacts
(grains.py), the shared command line (cli.py), the benches' reports (report.py) and the committed
materials (materials.py)."""
