"""The study: commands and protocols that turn scenes, frames, techniques and references into
tables and figures."""
