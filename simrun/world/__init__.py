"""The world: one MjSpec of named entities, its assets, compiled-model cache and the registry of scene types."""
