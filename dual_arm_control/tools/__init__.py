"""Command-line tools that talk to a running graph or read its bags."""
