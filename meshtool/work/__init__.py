"""Running many items: the batch layer (local or Dask), the worker pool, lifelines, progress, report parts."""
