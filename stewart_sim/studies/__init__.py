"""The studies: each returns data (study) and writes its files (report, files)."""
