"""`python -m benchmarks.stress`: the stress battery and the shipped models' cases, written
as the results file the hard-cases guide's table reads from."""
