from benchmarks.operations.cli import main

raise SystemExit(main())
