"""`python -m tools.bench`'s measurements, one module per scope: cases (one case, by execution path), submission
(POST to stored grade), classroom (a class at the deadline), memory (worker RSS), load (API latency); stack and
processes start the service on loopback, stats and tables summarise and print, run puts the parts in order, cli (run
by __main__) is the command line. Each returns plain figures; the CLI prints them and writes JSON.

Development tooling, not part of the installed package: run it from the repository root (`make bench`)."""
