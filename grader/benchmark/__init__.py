"""`grader bench`'s measurements, one module per scope: cases (one case, by execution path), submission (POST to
stored grade), classroom (a class at the deadline), memory (worker RSS), load (API latency); stack and processes start
the service on loopback, stats and tables summarise and print, run puts the parts in order. Each returns plain
figures; the CLI prints them and writes JSON."""
