"""placeholder"""
def main(args=None):
    pass
