"""Console scripts of the offline tools: one module per executable, named after it."""
