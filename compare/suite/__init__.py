"""The one reader of suite files: a TOML suite becomes a typed ``Suite`` (scenes, engine variants, settings)."""
