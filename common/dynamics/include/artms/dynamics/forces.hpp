// forces
