from benchmarks.family.cli import main

main()
