from benchmarks.nonholonomic.cli import main

raise SystemExit(main())
