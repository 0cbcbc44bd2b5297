"""``lightprobe demo``: the report of everything lightprobe does on one probe."""
