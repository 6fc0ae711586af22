"""The stiff and extreme cases shipped in scenes/stiff and scenes/extreme: a case run to its
outcome (outcome), reported against the expected one (report), the integrators compared on
them (study)."""
