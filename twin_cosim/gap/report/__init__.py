"""Stage 5 of a diagnosis: the verdict and what is left of the gap, in words and numbers for
people, the report's pages and its figures."""
