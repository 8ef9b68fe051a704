from benchmarks.stress.cli import main

main()
