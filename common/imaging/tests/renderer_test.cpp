// renderer tests
