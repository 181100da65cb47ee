"""The per-cycle control pipeline: modules run in order every 5 ms between input and driver."""
