"""`grader bench`'s measurements, one module per scope: cases (one case, by execution path) and the service
(a submission, a class, worker memory, API latency). Each returns plain figures; the CLI prints them and writes JSON."""
