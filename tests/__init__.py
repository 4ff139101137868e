"""The tests of wcs, one folder per part of the package (tests/contact/ tests wcs/contact/, tests/cli/
tests wcs/cli.py), acceptance/ for the cross-cutting contract and trust checks, bench/ for the
benchmarks and support/ for the helpers they share. Folders are packages, so a test module is
`tests.<part>.<name>` (two parts may each have a test_solver.py) and imports a helper as
`from tests.support.scenes import ...`."""
