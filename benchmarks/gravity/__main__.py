from benchmarks.gravity.cli import main

raise SystemExit(main())
