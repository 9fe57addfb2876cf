"""One adapter per engine library, all on the engine protocol of engines.adapter."""
