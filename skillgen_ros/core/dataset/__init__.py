"""Generated datasets: robomimic-layout HDF5, run reports and videos."""
