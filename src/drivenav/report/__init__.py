"""The run report: runs, their comparison and every episode as one static HTML site (``drivenav report``)."""
