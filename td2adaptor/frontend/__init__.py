"""Front end: load, validate, JSON-LD, Thing Models and the input dialects."""
