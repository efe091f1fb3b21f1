// gravity
