"""File formats of real captures, one module each with a reader and a writer (the writer is
what lets a round trip through simulated data test the reader)."""
