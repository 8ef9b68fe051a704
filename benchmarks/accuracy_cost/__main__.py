import sys

import bundledyn as bd
from benchmarks.accuracy_cost.cli import main

bd.use_cpu_xla_flags()  # before the first computation: importing starts no backend
main(sys.argv[1:])
