"""User tools built on the integrators: order verification, method choice, benchmarks,
reports, the loops' warm-up and the command line (``galerkin-vi``)."""
