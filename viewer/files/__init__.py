"""Files in standard formats, what kind a given file is, and which files this program wrote."""
