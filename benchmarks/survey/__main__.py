from benchmarks.survey.cli import main

main()
