"""The command-line programs (thin layers over library functions)."""
