"""`crossing-eval`: run driving policies over scenarios and seeds, and report safety and efficiency."""
