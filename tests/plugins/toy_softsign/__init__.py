"""toy_softsign: a test-only component, y = x / (scale + |x|), added as one folder (the way a
contributor adds a component) and registered by one line: ``register_folder(<this folder>)``."""
