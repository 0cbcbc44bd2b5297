"""``lightprobe batch``: thousands of probes into one columnar table, on one machine or a Dask cluster (top floor).

* :mod:`.inputs` — files, globs and lists of paths → the inputs, in a stable order.
* :mod:`.task` — what a worker does with one input: the single-file commands' own API calls, artifacts written
  atomically, one row (or one error) returned; it never raises.
* :mod:`.table` — the Parquet schema (versioned), part files committed by rename, the manifest, consolidation.
* :mod:`.runner` — the driver: a local process pool or Dask distributed, resumable and exactly-once.
* :mod:`.report` — the HTML page of a finished batch.
"""
