"""Independent reference models (numpy/scipy, no jaxdobby code) used to verify the package."""
