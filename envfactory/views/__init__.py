"""What people read about an env without running it: the describe tables (describe.py), the term catalog
(term_catalog.py) and the picture of the checked clearances (safety_picture.py)."""
