"""Linear analysis: linearization, stability, the paper's claims, root locus (pure)."""
