"""The `taa-study` command line and the scripted comparisons it offers (ab, bench)."""
