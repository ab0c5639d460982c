"""The workflow's glue: :mod:`.smk` (a rule's script wrapper: provenance, atomic outputs, one-line
errors), :mod:`.manifest` (every artifact hashed; ``oneocean verify``) and :mod:`.codeversion`
(the code a rule's outputs depend on)."""
