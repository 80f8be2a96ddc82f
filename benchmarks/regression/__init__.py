"""Results of the main paths recorded before a refactoring and compared after it."""
