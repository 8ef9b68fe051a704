from benchmarks.devices.cli import main

main()
