from benchmarks.tensorial.cli import main

raise SystemExit(main())
