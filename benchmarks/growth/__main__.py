from benchmarks.growth.cli import main

raise SystemExit(main())
