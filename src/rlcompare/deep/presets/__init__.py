"""Each deep method's settings, validated on creation, and its named presets with their sources."""
