"""Studies over seeds and datasets: pooled Table 1, hierarchical intervals, headroom."""
