"""Starting the service as real processes, for the benchmark (tools.bench) and the integration tests alike."""
