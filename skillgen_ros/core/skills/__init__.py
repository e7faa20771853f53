"""Source demos as the paper defines them: annotated skill segments stored in object frames."""
