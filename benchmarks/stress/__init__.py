"""`python -m benchmarks.stress`: the stress battery and the shipped models' cases, written
as the results file the README's table reads from."""
