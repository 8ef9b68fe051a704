import sys

import bundledyn as bd
from benchmarks.identification.cli import main

bd.use_cpu_xla_flags()  # before the first computation: importing starts no backend
main(sys.argv[1:])
