"""``python -m models.native``: build the compiled kernels (``make setup`` / ``make fmus``)."""

from models.native import build, status

if __name__ == "__main__":
    print(f"built {build()}; models use: {status()}")
