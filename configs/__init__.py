"""ml_collections configs, one file per experiment; ``get_config('paper' | 'cpu' | 'tiny')``."""
