"""The analysis: streaming checks, predictions, the verdict, offline analysis (pure)."""
