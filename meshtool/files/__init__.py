"""Files: the resolver, race-free bounded opens, atomic outputs, recognisers, cache envelopes, nesting bounds."""
