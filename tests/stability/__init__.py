"""Hard-case stability suite: property-based (hypothesis, derandomized) and table-driven tests across the core."""
