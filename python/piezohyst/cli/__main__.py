from .main import run

# guarded: Dask's worker processes (multiprocessing spawn) import the main module again
if __name__ == "__main__":
    run()
