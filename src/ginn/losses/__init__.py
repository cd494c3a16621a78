"""Loss terms: constraints (Table 1 and more) and diversity."""
